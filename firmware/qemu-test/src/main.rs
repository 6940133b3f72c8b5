//! The protocol player on the real instruction set, under QEMU (`netduinoplus2`).
//!
//! Plays every slot of a bank linked into the BANK flash region, one tick per
//! 1 kHz SysTick interrupt, hashes the codes and compares them with what the host's
//! player computed at build time. Under `-icount` SysTick counts instructions, so
//! the cost of each tick is measured on the target's instruction set. The verdict is
//! the semihosting exit code.
#![no_std]
#![no_main]

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::Mutex;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use sleeve_firmware::boot::{check_bank, BootError};
use sleeve_firmware::button::{Buttons, Mode};
use sleeve_firmware::control::Controller;
use sleeve_firmware::engine::{Engine, Watchdog};
use sleeve_firmware::link::port::STAGED_STREAM;
use sleeve_firmware::link::{Channels, Control, LinkPort};
use sleeve_firmware::output::{device_config, pwm_compare, Frame, PWM_PERIOD};
use sleeve_qemu_shared::{crc32, scenario};
use touch_protocol::bank::{REGION_ADDR, REGION_LEN};
use touch_protocol::link::StreamParams;
use touch_protocol::player::{DeviceConfig, Player, Status};
use touch_protocol::{Bank, OutputSink, CHANNELS};

include!(concat!(env!("OUT_DIR"), "/expected.rs"));

/// The test bank, at the start of the BANK region like a flashed `sleeve.bank`.
#[used]
#[unsafe(link_section = ".bank")]
static BANK: [u8; include_bytes!(concat!(env!("OUT_DIR"), "/bank.bin")).len()] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/bank.bin"));

/// The boot check's worst case, a full region of dense records (every keyframe a
/// one-step change of one channel, about 12 bits each; in code flash).
static DENSE: [u8; include_bytes!(concat!(env!("OUT_DIR"), "/dense.bin")).len()] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/dense.bin"));

/// The bound the boot check must stay under, instructions: the boot watchdog's
/// 1 s timeout (`src/hw/tick.rs`) is 168 M cycles, which leaves 3 cycles per
/// instruction (flash wait states, taken branches).
const BOOT_CHECK_BOUND_INSNS: u64 = 56_000_000;

/// SysTick wraps while no job runs (for spans longer than one tick).
static WRAPS: AtomicU32 = AtomicU32::new(0);

/// SysTick counts at the 168 MHz core clock: 168,000 counts per 1 kHz tick.
const RELOAD: u32 = 168_000 - 1;

/// SysTick counts per instruction under `-icount shift=4` (16 ns each): 16 * 0.168.
const COUNTS_PER_INSN_X1000: u32 = 2688;

/// TIM3 and TIM4 capture/compare registers (CCR1-4 at offset 0x34), which QEMU
/// emulates: the engine's frames go to the real registers, as in the firmware.
const CCR: [usize; 2] = [0x4000_0434, 0x4000_0834];

/// Writes frames to the timers' compare registers and keeps the last for the hash.
struct Ccr(Frame);
impl OutputSink for Ccr {
    fn write(&mut self, codes: &Frame) {
        for (c, &code) in codes.iter().enumerate() {
            let reg = (CCR[c / 4] + 4 * (c % 4)) as *mut u32;
            // SAFETY: a TIM3/TIM4 CCR register, word-aligned, write-only use.
            unsafe { reg.write_volatile(pwm_compare(code, PWM_PERIOD)) };
        }
        self.0 = *codes;
    }
}

/// No watchdog under QEMU.
struct NoDog;
impl Watchdog for NoDog {
    fn feed(&mut self) {}
}

/// What the SysTick handler steps.
// One at a time, in a static: the size difference costs nothing.
#[allow(clippy::large_enum_variant)]
enum Job {
    /// The protocol player alone, one slot.
    Player(Player<'static>),
    /// The firmware's whole tick: buttons, controller, player, output write.
    Engine(Engine<'static, Ccr, NoDog, 1>),
    /// The same with the link attached and busy: its end of the queues, driven
    /// between ticks as the link's task would (see [`host_side`]).
    Linked(
        Engine<'static, Ccr, NoDog, 1>,
        LinkPort<'static, 'static>,
        Bank<'static>,
    ),
}

/// The most instructions a playing tick may take with the link busy (a command every
/// tick and a stream fed through it): the player's tick has to fit a 1 kHz period
/// with the interrupts of the buttons and the link beside it.
const LINK_BUSY_BUDGET_INSNS: u32 = 1_700;

/// Ticks the link-busy run lasts.
const LINK_TICKS: u32 = 4000;

/// How the link-busy run's stream plays.
const STREAM: StreamParams = StreamParams {
    keyframe_period_ms: 20,
    ramp_ms: 20,
    full_scale_ma: 1000,
    limits: touch_protocol::Limits::SLEEVE,
};

/// The link's task between two ticks: a command for the tick every millisecond
/// (a stream begun at once and fed a keyframe every 20 ms, then a stop, a play, a
/// stop, and a status request whenever nothing else is due), the player the tick
/// wants built (as the link server does), and the answers taken.
fn host_side(t: u32, port: &mut LinkPort<'static, 'static>, bank: Bank<'static>) {
    let stage = |port: &mut LinkPort<'static, 'static>, slot: u8| {
        port.stage(slot, || {
            let s = bank.slot(usize::from(slot)).ok()?;
            Some(Player::with_thermal(
                &s,
                &device_config(),
                touch_protocol::Thermal::COLD,
            ))
        })
    };
    if let Some(slot) = port.wanted() {
        if port.staged() != Some(slot) {
            stage(port, slot);
        }
    }
    let seq = t as u16;
    if t == 2300 {
        stage(port, 0);
    }
    let control = match t {
        0 => Control::StreamBegin {
            seq,
            params: STREAM,
        },
        2000 | 3500 => Control::Stop { seq },
        2300 => Control::Play { seq, slot: 0 },
        _ => Control::Status { seq },
    };
    let _ = port.send(control);
    if t < 2000 && t % 20 == 1 {
        // Two keyframes ahead: a triangle on every channel, up to 0.9 A.
        let k = ((t / 20) % 20) as i32;
        let v = (if k < 10 { k } else { 20 - k } * 2949) as i16;
        let n = if t == 1 { 3 } else { 1 };
        for _ in 0..n {
            let _ = port.push_keyframe([v; CHANNELS]);
        }
        if t == 1 {
            // The stream's player from its first two keyframes, as the link server
            // builds it.
            port.stage(STAGED_STREAM, || {
                Some(Player::live(
                    &STREAM,
                    [v; CHANNELS],
                    [v; CHANNELS],
                    &device_config(),
                    touch_protocol::Thermal::COLD,
                ))
            });
        }
        port.fed();
    }
    while port.receive().is_some() {}
}

struct State {
    job: Job,
    ticks: u32,
    crc: u32,
    faulted: bool,
    done: bool,
    max_counts: u32,
    sum_counts: u64,
    /// The worst tick while a stream plays steadily (the link run only).
    steady_counts: u32,
}

impl State {
    fn new(job: Job) -> Self {
        State {
            job,
            ticks: 0,
            crc: !0,
            faulted: false,
            done: false,
            max_counts: 0,
            sum_counts: 0,
            steady_counts: 0,
        }
    }

    /// Worst and mean instructions per tick.
    fn insns(&self) -> (u32, u32) {
        let max = self.max_counts * 1000 / COUNTS_PER_INSN_X1000;
        let mean = self.sum_counts * 1000
            / u64::from(COUNTS_PER_INSN_X1000)
            / u64::from(self.ticks.max(1));
        (max, mean as u32)
    }
}

static STATE: Mutex<RefCell<Option<State>>> = Mutex::new(RefCell::new(None));

fn bank_region() -> &'static [u8] {
    // SAFETY: internal flash, mapped for the life of the program, never written.
    unsafe { core::slice::from_raw_parts(REGION_ADDR as *const u8, REGION_LEN) }
}

#[entry]
fn main() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap_or_else(|| fail("peripherals taken"));
    // Read through the region, not the static: this checks the link placement too.
    let bank = match Bank::decode(bank_region()) {
        Ok(bank) => bank,
        Err(_) => fail("bank in flash refused"),
    };
    if BANK.as_ptr() as usize != REGION_ADDR || bank.len() != EXPECTED.len() {
        fail("bank not at 0x080C0000 or wrong slot count");
    }
    let boot_ok = check_boot();
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(RELOAD);
    cp.SYST.clear_current();
    // Every check runs (and prints its figures) whatever the ones before it found.
    let ok = boot_ok
        & calibrate(&mut cp.SYST)
        & check_boot_bound(&mut cp.SYST)
        & check_player(&mut cp.SYST, bank)
        & check_engine(&mut cp.SYST, bank)
        & check_link_busy(&mut cp.SYST, bank);
    hprintln!(
        "{} passed, {} failed",
        if ok { 1 } else { 0 },
        if ok { 0 } else { 1 }
    );
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}

/// The firmware's boot check, on the target: accepts the linked bank, refuses an
/// erased region and a corrupted copy of the bank.
fn check_boot() -> bool {
    let mut copy = [0u8; BANK.len()];
    copy.copy_from_slice(&BANK);
    copy[BANK.len() / 2] ^= 0x10;
    let erased = [0xFFu8; 64];
    let boot_ok = check_bank(bank_region()).is_ok()
        && matches!(check_bank(&erased), Err(BootError::Empty))
        && matches!(check_bank(&copy), Err(BootError::Corrupt(_)));
    hprintln!(
        "boot check: good bank accepted, erased and corrupted refused: {}",
        if boot_ok { "ok" } else { "FAILED" }
    );
    boot_ok
}

/// Calibration: 1000 NOPs (plus the two SysTick reads) must count ~1000
/// instructions, else the -icount shift and COUNTS_PER_INSN_X1000 disagree.
fn calibrate(syst: &mut SYST) -> bool {
    syst.enable_counter();
    let start = SYST::get_current();
    // SAFETY: NOPs only.
    unsafe { core::arch::asm!(".rept 1000", "nop", ".endr", options(nomem, nostack)) };
    let end = SYST::get_current();
    syst.disable_counter();
    let nop_insns = elapsed(start, end) * 1000 / COUNTS_PER_INSN_X1000;
    hprintln!("calibration: 1000 nops measure {} instructions", nop_insns);
    (1000..1010).contains(&nop_insns)
}

/// The boot check's bound: a full region of the densest records.
fn check_boot_bound(syst: &mut SYST) -> bool {
    let (dense_ok, dense_insns) = span_insns(syst, || check_bank(&DENSE).is_ok());
    let bound_ok = dense_ok && dense_insns < BOOT_CHECK_BOUND_INSNS;
    hprintln!(
        "boot check of a full {}-byte region of dense records: {} instructions (bound {}): {}",
        DENSE.len(),
        dense_insns,
        BOOT_CHECK_BOUND_INSNS,
        if bound_ok { "ok" } else { "FAILED" }
    );
    bound_ok
}

/// The protocol player alone on every slot: the codes' hash, tick count and fault
/// against the host's, and the instructions per tick.
fn check_player(syst: &mut SYST, bank: Bank<'static>) -> bool {
    let device = DeviceConfig::default();
    let mut ok = true;
    let mut worst_insns = 0;
    for (slot, &(ticks, crc, faulted)) in EXPECTED.iter().enumerate() {
        let stim = bank.slot(slot).unwrap_or_else(|_| fail("slot refused"));
        let state = State::new(Job::Player(Player::new(&stim, &device)));
        let s = run(syst, state);
        let got_crc = !s.crc;
        let (max_insns, mean_insns) = s.insns();
        worst_insns = worst_insns.max(max_insns);
        let pass = s.ticks == ticks && got_crc == crc && s.faulted == faulted;
        ok &= pass;
        hprintln!(
            "slot {} '{}': {} ticks (host {}), crc {:#010x} (host {:#010x}), fault {} (host {}), insns/tick max {} mean {}: {}",
            slot,
            stim.name(),
            s.ticks,
            ticks,
            got_crc,
            crc,
            s.faulted,
            faulted,
            max_insns,
            mean_insns,
            if pass { "ok" } else { "MISMATCH" }
        );
    }
    hprintln!(
        "player: instructions per 1 kHz tick (8 channels), worst: {}",
        worst_insns
    );
    ok
}

/// The firmware's engine through the button scenario, codes to TIM3/TIM4.
fn check_engine(syst: &mut SYST, bank: Bank<'static>) -> bool {
    let controller = Controller::new(bank, device_config());
    let engine = Engine::new(
        Ccr([0; CHANNELS]),
        NoDog,
        Buttons::<1>::new(Mode::PlayNext),
        controller,
    );
    let state = State::new(Job::Engine(engine));
    let s = run(syst, state);
    let got = !s.crc;
    let (max_insns, mean_insns) = s.insns();
    let pass = got == ENGINE_CRC && s.ticks == scenario::TICKS;
    hprintln!(
        "engine scenario: {} ticks, crc {:#010x} (host {:#010x}), insns/tick max {} mean {}: {}",
        s.ticks,
        got,
        ENGINE_CRC,
        max_insns,
        mean_insns,
        if pass { "ok" } else { "MISMATCH" }
    );
    hprintln!(
        "firmware tick (buttons + controller + player + CCR writes), worst: {}",
        max_insns
    );
    pass
}

/// The same tick with the link attached and a command queued every tick: the
/// stream plays, and its ticks stay within [`LINK_BUSY_BUDGET_INSNS`].
fn check_link_busy(syst: &mut SYST, bank: Bank<'static>) -> bool {
    static mut LINK_QUEUES: Channels = Channels::new();
    // SAFETY: split once, here (this check runs once); each end has one owner from
    // now on.
    let (link_port, tick_port) = unsafe { (*core::ptr::addr_of_mut!(LINK_QUEUES)).split() };
    let mut controller = Controller::new(bank, device_config());
    controller.attach(tick_port);
    let engine = Engine::new(
        Ccr([0; CHANNELS]),
        NoDog,
        Buttons::<1>::new(Mode::PlayNext),
        controller,
    );
    let s = run(syst, State::new(Job::Linked(engine, link_port, bank)));
    let (max_insns, mean_insns) = s.insns();
    let streamed = s.faulted;
    let steady = s.steady_counts * 1000 / COUNTS_PER_INSN_X1000;
    hprintln!(
        "firmware tick with the link busy (a command every tick, a stream, play, stop): {} ticks, insns/tick max {} mean {}, while the stream plays max {} (budget {}), stream played: {}",
        s.ticks,
        max_insns,
        mean_insns,
        steady,
        LINK_BUSY_BUDGET_INSNS,
        if streamed { "ok" } else { "FAILED" }
    );
    streamed && steady < LINK_BUSY_BUDGET_INSNS
}

#[exception]
fn SysTick() {
    cortex_m::interrupt::free(|cs| {
        let mut cell = STATE.borrow(cs).borrow_mut();
        let Some(s) = cell.as_mut() else {
            WRAPS.fetch_add(1, Ordering::Relaxed);
            return;
        };
        if s.done {
            return;
        }
        // SysTick counts down from RELOAD: the counts spent are start - end.
        let t = s.ticks;
        // Only the tick itself is measured, not the bookkeeping around it.
        let (codes, status, start, end) = match &mut s.job {
            Job::Player(player) => {
                let start = SYST::get_current();
                let tick = player.tick();
                let end = SYST::get_current();
                (tick.codes, Some(tick.status), start, end)
            }
            Job::Engine(engine) => {
                let edges = [scenario::edge(t)];
                let start = SYST::get_current();
                engine.tick(edges, |_| {}, || {});
                let end = SYST::get_current();
                (engine.sink().0, None, start, end)
            }
            Job::Linked(engine, port, bank) => {
                host_side(t, port, *bank);
                let start = SYST::get_current();
                engine.tick([None], |_| {}, || {});
                let end = SYST::get_current();
                // `faulted` marks here that the stream still plays near its end (not 0 A).
                let frame = engine.sink().0;
                if (100..1900).contains(&t) {
                    s.steady_counts = s.steady_counts.max(elapsed(start, end));
                }
                s.faulted |= t == 1900 && frame.iter().any(|&c| c != touch_protocol::IDLE_CODE);
                (frame, None, start, end)
            }
        };
        let spent = elapsed(start, end);
        s.max_counts = s.max_counts.max(spent);
        s.sum_counts += u64::from(spent);
        s.ticks += 1;
        s.crc = crc32::update_frame(s.crc, &codes);
        s.faulted |= matches!(status, Some(Status::Fault(_)));
        s.done = match status {
            Some(status) => status == Status::Finished || s.ticks > 1_000_000,
            None if matches!(s.job, Job::Linked(..)) => s.ticks >= LINK_TICKS,
            None => s.ticks >= scenario::TICKS,
        };
    });
}

/// Runs one job at 1 kHz until it is done; returns its final state.
fn run(syst: &mut SYST, state: State) -> State {
    cortex_m::interrupt::free(|cs| STATE.borrow(cs).replace(Some(state)));
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    loop {
        cortex_m::asm::wfi();
        let done = cortex_m::interrupt::free(|cs| {
            STATE.borrow(cs).borrow().as_ref().is_some_and(|s| s.done)
        });
        if done {
            syst.disable_interrupt();
            syst.disable_counter();
            let s = cortex_m::interrupt::free(|cs| STATE.borrow(cs).borrow_mut().take());
            return s.unwrap_or_else(|| fail("state lost"));
        }
    }
}

/// Runs `f` with SysTick counting wraps; returns its result and the instructions spent.
fn span_insns<T>(syst: &mut SYST, f: impl FnOnce() -> T) -> (T, u64) {
    WRAPS.store(0, Ordering::Relaxed);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    let start = SYST::get_current();
    let r = f();
    let end = SYST::get_current();
    let wraps = WRAPS.load(Ordering::Relaxed);
    syst.disable_interrupt();
    syst.disable_counter();
    // Counting down: each wrap adds a whole period.
    let counts = u64::from(wraps) * u64::from(RELOAD + 1) + u64::from(start) - u64::from(end);
    (r, counts * 1000 / u64::from(COUNTS_PER_INSN_X1000))
}

/// SysTick counts spent between two reads of the down-counter (at most one wrap).
fn elapsed(start: u32, end: u32) -> u32 {
    (start + RELOAD + 1 - end) % (RELOAD + 1)
}

fn fail(why: &str) -> ! {
    hprintln!("qemu-test failed: {}", why);
    hprintln!("0 passed, 1 failed");
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("qemu-test panicked: {}", info);
    hprintln!("0 passed, 1 failed");
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
