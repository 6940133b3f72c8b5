//! Everything that touches the STM32F405RG. The logic lives in the library.

pub mod board;
pub mod outputs;
pub mod tick;

use defmt::{error, info, warn};
use embassy_executor::Spawner;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Async;
use embassy_time::{with_timeout, Duration, Timer};
use sleeve_firmware::boot::{bank_source, check_bank, BootError};
use sleeve_firmware::button::{boot_events, Buttons, EdgeMailbox, DEBOUNCE_TICKS};
use sleeve_firmware::control::{Controller, Report};
use sleeve_firmware::engine::Engine;
use sleeve_firmware::output::device_config;

use board::BUTTONS;

/// The bank region of `memory.x`: sectors 10-11.
const BANK_ADDR: usize = 0x080C_0000;
/// Length of the bank region.
const BANK_LEN: usize = 256 * 1024;

/// A default bank, linked into the BANK region (feature `default-bank`).
#[cfg(feature = "default-bank")]
#[used]
#[unsafe(link_section = ".bank")]
static DEFAULT_BANK: [u8; include_bytes!(env!("SLEEVE_DEFAULT_BANK_PATH")).len()] =
    *include_bytes!(env!("SLEEVE_DEFAULT_BANK_PATH"));

/// The built-in emoji bank (`examples/emoji/`), in the code region: played when the
/// bank region is erased, so a freshly flashed sleeve plays on the first press.
static EMOJI_BANK: &[u8] = include_bytes!("../../../examples/emoji/emoji.bank");

/// The whole bank region of flash.
fn bank_region() -> &'static [u8] {
    // SAFETY: the region is internal flash, mapped and readable for the life of the
    // program, and nothing writes it while the firmware runs.
    unsafe { core::slice::from_raw_parts(BANK_ADDR as *const u8, BANK_LEN) }
}

/// Boots: outputs at 0 A, bank check, then the 1 kHz tick and the button tasks.
pub async fn run(spawner: Spawner) -> ! {
    let p = embassy_stm32::init(board::config());
    let board::Board {
        outputs,
        buttons,
        mut led,
        iwdg,
        tick: tim7,
    } = board::take(p);
    info!("sleeve: outputs at 0 A");
    // The buttons next: their tasks arm EXTI at their first poll (the yield), so a
    // press during the rest of the boot is posted, and latched (see `boot_events`).
    for (i, button) in buttons.into_iter().enumerate() {
        spawner.spawn(defmt::unwrap!(button_task(button, &tick::EDGES[i])));
    }
    Timer::after_millis(1).await;

    let source = bank_source(bank_region(), EMOJI_BANK);
    if core::ptr::eq(source, EMOJI_BANK) {
        info!("bank region erased: playing the built-in emoji bank");
    }
    let bank = match check_bank(source) {
        Ok(bank) => bank,
        Err(e) => {
            error!("bank refused, nothing plays: {}", e);
            blink_forever(&mut led, e).await
        }
    };
    info!("bank: {} slots", bank.len());
    for (i, s) in bank.stimuli().enumerate() {
        info!("  slot {}: {} ({} ms)", i, s.name(), s.duration_ms());
    }

    let controller = Controller::new(bank, device_config());
    let mut engine = Engine::new(
        outputs,
        tick::Iwdg::start(iwdg),
        Buttons::<BUTTONS>::new(board::BUTTON_MODE),
        controller,
    );
    // Let the button tasks post what happened while the bank was checked.
    Timer::after_millis(1).await;
    for event in boot_events(board::BUTTON_MODE, &tick::EDGES) {
        if let Some(report) = engine.inject(event) {
            info!("press during boot:");
            show(report, &mut led);
        }
    }
    tick::start(engine, tim7);
    info!("ready: press to play slot 0, hold to select the next");

    loop {
        show(tick::REPORTS.receive().await, &mut led);
    }
}

/// Logs a report and shows it on the LED (on while a slot plays). Every report goes
/// through here, those of presses during boot included, so the LED never misses one.
fn show(report: Report, led: &mut Output<'static>) {
    match report {
        Report::Fault(..) => warn!("limit hit, ramping to 0 A: {}", report),
        Report::BadSlot(_) => error!("{}", report),
        _ => info!("{}", report),
    }
    match report {
        Report::Started(_) => led.set_high(),
        Report::Finished(_) => led.set_low(),
        _ => {}
    }
}

/// Posts every edge of one button, with the level read after it. After a quiet
/// debounce window the level is posted again, so an edge that came while this task
/// was not yet waiting still ends in the right level. An edge that reads the same
/// level as before was a whole press (or glitch) while the task was busy or not yet
/// running: it is posted as both, so the press latch sees it.
#[embassy_executor::task(pool_size = 4)]
async fn button_task(mut button: ExtiInput<'static, Async>, mailbox: &'static EdgeMailbox) {
    // The level at start counts: a button held through boot is a press.
    let mut last = board::pressed(&button);
    mailbox.post(last);
    let window = Duration::from_millis(u64::from(DEBOUNCE_TICKS));
    let post = |level: bool, last: &mut bool| {
        if level == *last {
            mailbox.post(!level);
        }
        mailbox.post(level);
        *last = level;
    };
    loop {
        button.wait_for_any_edge().await;
        post(board::pressed(&button), &mut last);
        while with_timeout(window, button.wait_for_any_edge())
            .await
            .is_ok()
        {
            post(board::pressed(&button), &mut last);
        }
        // Quiet: re-read without inventing an edge.
        last = board::pressed(&button);
        mailbox.post(last);
    }
}

/// The refused-bank LED code: `blinks` short flashes, a pause, forever.
async fn blink_forever(led: &mut Output<'static>, e: BootError) -> ! {
    loop {
        for _ in 0..e.blinks() {
            led.set_high();
            Timer::after_millis(150).await;
            led.set_low();
            Timer::after_millis(250).await;
        }
        Timer::after_millis(1200).await;
    }
}

/// On panic: every channel to 0 A, say why, stop. The watchdog, no longer fed,
/// then resets the MCU, which boots with the outputs at 0 A and nothing playing.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    outputs::force_idle();
    error!("panic, outputs at 0 A: {}", defmt::Display2Format(info));
    loop {
        cortex_m::asm::nop();
    }
}

/// On a hard fault: the same as a panic.
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    outputs::force_idle();
    loop {
        cortex_m::asm::nop();
    }
}
