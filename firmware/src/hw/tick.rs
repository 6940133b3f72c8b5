//! The 1 kHz tick: TIM7's update interrupt steps the [`Engine`].

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicU8, Ordering};

use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{IWDG, TIM7};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{interrupt, pac, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use heapless::spsc::{Consumer, Producer, Queue};
use sleeve_firmware::button::EdgeMailbox;
use sleeve_firmware::control::Report;
use sleeve_firmware::engine::{Engine, Watchdog};

use super::board::BUTTONS;
use super::outputs::Outputs;

/// The watchdog times out if the tick stalls this long (50 ticks).
const WATCHDOG_TIMEOUT_US: u32 = 50_000;

/// The watchdog's timeout during boot, before the tick runs: above the boot check's
/// bound (`boot::check_bank`: at most 32 M instructions for a full 256 KB region,
/// measured under QEMU; at most 3 cycles each at 168 MHz is 0.57 s).
const BOOT_WATCHDOG_TIMEOUT_US: u32 = 1_000_000;

/// The independent watchdog (LSI, about 32 kHz): fed by the boot, then by the tick.
pub struct Iwdg(IndependentWatchdog<'static, IWDG>);

impl Iwdg {
    /// Starts the watchdog with the boot timeout, before anything reads the bank.
    pub fn start(iwdg: Peri<'static, IWDG>) -> Self {
        let mut dog = IndependentWatchdog::new(iwdg, BOOT_WATCHDOG_TIMEOUT_US);
        dog.unleash();
        Iwdg(dog)
    }

    /// Shortens the timeout to the tick's 50 ms, once the boot's slow work is done.
    pub fn tighten(&mut self) {
        use embassy_stm32::pac::iwdg::vals::{Key, Pr};
        self.0.pet();
        let w = pac::IWDG;
        // 32 kHz / 4 = 8 kHz: 400 counts are 50 ms.
        const RELOAD: u16 = (WATCHDOG_TIMEOUT_US / 125) as u16 - 1;
        w.kr().write(|k| k.set_key(Key::ENABLE));
        w.pr().write(|p| p.set_pr(Pr::DIVIDE_BY4));
        w.rlr().write(|r| r.set_rl(RELOAD));
        // The new values reach the watchdog's clock domain a few LSI cycles later.
        while {
            let sr = w.sr().read();
            sr.pvu() || sr.rvu()
        } {}
        self.0.pet();
    }
}

impl Watchdog for Iwdg {
    fn feed(&mut self) {
        self.0.pet();
    }
}

/// The engine as the firmware runs it.
pub type SleeveEngine = Engine<'static, Outputs, Iwdg, BUTTONS>;

/// Written once by [`start`] before TIM7's interrupt is enabled, then owned by the
/// handler. Uninitialised rather than an `Option`: a `None` of this type is not all
/// zeros, so it would sit in `.data` and copy its 2.7 KB image from flash.
static mut ENGINE: MaybeUninit<SleeveEngine> = MaybeUninit::uninit();

/// Button edges, from the EXTI tasks to the tick.
pub static EDGES: [EdgeMailbox; BUTTONS] = [const { EdgeMailbox::new() }; BUTTONS];

/// Reports in flight from the tick to the log (one fewer than this). Full means
/// dropped, never blocked.
const REPORT_DEPTH: usize = 17;

/// What the tick reports, for the log: the tick fills it, [`Reports`] empties it.
static mut REPORT_QUEUE: Queue<Report, REPORT_DEPTH> = Queue::new();

/// The tick's end of [`REPORT_QUEUE`], set by `install` before the tick starts.
static mut REPORT_TX: MaybeUninit<Producer<'static, Report, REPORT_DEPTH>> = MaybeUninit::uninit();

/// Signalled by [`FOLLOW_UP`]'s handler when the tick queued reports.
static REPORTED: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// What the tick left to its follow-up interrupt ([`FOLLOW_UP`]).
static FOLLOW: AtomicU8 = AtomicU8::new(0);
/// [`FOLLOW`]: wake the link's task (answers queued, or a player wanted).
const FOLLOW_LINK: u8 = 1;
/// [`FOLLOW`]: reports queued for the log.
const FOLLOW_REPORTS: u8 = 2;

/// The tick's follow-up: an interrupt no peripheral of the board raises, which the
/// tick pends and which runs once it returned, below its priority. Waking a task
/// from the tick itself (a critical section and the executor's waker) costs the
/// tick some 45 instructions each; pending this costs it a store.
const FOLLOW_UP: interrupt::Interrupt = interrupt::Interrupt::SPI3;

/// The tick's priority once it wrote its frame and fed the watchdog, while it
/// computes the next frame (see [`Engine::tick`]): below the link's interrupts
/// (USART2 and OTG_FS at P2), level with the follow-up, which the tick pends only
/// after it.
const COMPUTE_PRIORITY: Priority = Priority::P3;

/// The engine in its place for the tick, before the tick runs.
pub struct Tick {
    engine: &'static mut SleeveEngine,
    reports: Reports,
    _tim7: Peri<'static, TIM7>,
}

/// The log's end of the tick's reports.
pub struct Reports(Consumer<'static, Report, REPORT_DEPTH>);

impl Reports {
    /// The next report, when the tick has one.
    pub async fn next(&mut self) -> Report {
        loop {
            if let Some(r) = self.0.dequeue() {
                return r;
            }
            REPORTED.wait().await;
        }
    }
}

/// Puts the engine where the tick interrupt will own it (it is not moved again).
pub fn install(engine: SleeveEngine, tim7: Peri<'static, TIM7>) -> Tick {
    // SAFETY: `install` runs once (it takes the TIM7 singleton), and the interrupt
    // that reads ENGINE and REPORT_TX is enabled only by `Tick::start`, which gives
    // up this borrow. The report queue is split once, here.
    let (engine, rx) = unsafe {
        let engine = (*addr_of_mut!(ENGINE)).write(engine);
        let (tx, rx) = (*addr_of_mut!(REPORT_QUEUE)).split();
        (*addr_of_mut!(REPORT_TX)).write(tx);
        (engine, rx)
    };
    Tick {
        engine,
        reports: Reports(rx),
        _tim7: tim7,
    }
}

impl Tick {
    /// The engine, until the tick starts.
    pub fn engine(&mut self) -> &mut SleeveEngine {
        self.engine
    }

    /// Hands the engine to the tick interrupt and starts TIM7 at 1 kHz; returns the
    /// log's end of the reports.
    pub fn start(self) -> Reports {
        FOLLOW_UP.set_priority(Priority::P3);
        // SAFETY: its handler below only touches the FOLLOW flags and two signals.
        unsafe { FOLLOW_UP.enable() };
        embassy_stm32::rcc::enable_and_reset::<TIM7>();
        let t = pac::TIM7;
        // 84 MHz / 84 = 1 MHz; 1000 counts = 1 ms.
        t.psc().write_value(83);
        t.arr().write(|w| w.set_arr(999));
        t.egr().write(|w| w.set_ug(true));
        t.sr().write(|w| w.set_uif(false));
        t.dier().modify(|w| w.set_uie(true));
        // The highest priority: nothing preempts the frame write at the start of the tick.
        interrupt::TIM7.set_priority(Priority::P0);
        // SAFETY: the handler below only touches ENGINE and REPORT_TX (written by
        // `install`, its borrow given up with `self`), the mailboxes and the FOLLOW
        // flags, all of which are ready.
        unsafe { interrupt::TIM7.enable() };
        t.cr1().modify(|w| w.set_cen(true));
        self.reports
    }
}

#[interrupt]
fn TIM7() {
    pac::TIM7.sr().write(|w| w.set_uif(false));
    // SAFETY: this interrupt is enabled only after `install` wrote ENGINE, and from
    // then on only this handler touches it. At the highest priority nothing preempts
    // it to run it again (an interrupt does not preempt one of its own priority).
    let (engine, reports) = unsafe {
        (
            (*addr_of_mut!(ENGINE)).assume_init_mut(),
            (*addr_of_mut!(REPORT_TX)).assume_init_mut(),
        )
    };
    let edges = core::array::from_fn(|i| EDGES[i].take());
    let mut follow = 0;
    engine.tick(
        edges,
        |report| {
            if reports.enqueue(report).is_ok() {
                follow |= FOLLOW_REPORTS;
            }
        },
        || {
            // The frame is out and the watchdog fed: the next frame is computed
            // below the link's interrupts, so that they wait for the write alone.
            // TIM7 is active: it cannot preempt itself, so the engine stays this
            // handler's alone.
            interrupt::TIM7.set_priority(COMPUTE_PRIORITY);
        },
    );
    interrupt::TIM7.set_priority(Priority::P0);
    if engine.controller().link_answered() {
        follow |= FOLLOW_LINK;
    }
    if follow != 0 {
        FOLLOW.fetch_or(follow, Ordering::Release);
        FOLLOW_UP.pend();
    }
}

/// The tick's follow-up (see [`FOLLOW_UP`]): wakes what the tick left to wake.
#[interrupt]
fn SPI3() {
    let follow = FOLLOW.swap(0, Ordering::Acquire);
    if follow & FOLLOW_LINK != 0 {
        super::link::wake();
    }
    if follow & FOLLOW_REPORTS != 0 {
        REPORTED.signal(());
    }
}
