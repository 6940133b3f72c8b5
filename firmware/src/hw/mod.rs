//! Everything that touches the STM32F405RG. The logic lives in the library.

pub mod board;
pub mod flash;
pub mod link;
#[cfg(feature = "usb")]
pub mod otg;
pub mod outputs;
pub mod tick;
#[cfg(feature = "usb")]
pub mod usb;

use defmt::{error, info, warn};
use embassy_executor::Spawner;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Async;
use embassy_time::{with_deadline, with_timeout, Duration, Instant, Timer};
use sleeve_firmware::boot::{bank_source, check_bank, BootError};
use sleeve_firmware::button::{boot_events, Buttons, EdgeMailbox, DEBOUNCE_TICKS};
use sleeve_firmware::control::{Controller, Report};
use sleeve_firmware::engine::{Engine, Watchdog};
use sleeve_firmware::led::{Led, Pattern};
use sleeve_firmware::link::server::identity;
use sleeve_firmware::link::{Channels, LinkServer};
use sleeve_firmware::output::device_config;
use touch_protocol::bank::{REGION_ADDR, REGION_LEN};

use board::BUTTONS;

/// A default bank, linked into the BANK region (feature `default-bank`).
#[cfg(feature = "default-bank")]
#[used]
#[unsafe(link_section = ".bank")]
static DEFAULT_BANK: [u8; include_bytes!(concat!(env!("OUT_DIR"), "/default.bank")).len()] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/default.bank"));

/// The built-in emoji bank (`firmware/emoji.bank`, the one `examples/emoji/` makes), in
/// the code region: played when the bank region is erased, so a freshly flashed sleeve
/// plays on the first press. The build script puts it in `OUT_DIR`.
static EMOJI_BANK: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/emoji.bank"));

/// The whole bank region of flash.
fn bank_region() -> &'static [u8] {
    // SAFETY: the region is internal flash, mapped and readable for the life of the
    // program. Only the link's bank writer changes it (`flash.rs`), and only after the
    // tick locked the bank out of playback: the stimuli borrowed at boot are not read
    // again before the restart that follows an upload.
    unsafe { core::slice::from_raw_parts(REGION_ADDR as *const u8, REGION_LEN) }
}

/// Boots: outputs at 0 A, bank check, then the 1 kHz tick and the button tasks.
pub async fn run(spawner: Spawner) -> ! {
    let p = embassy_stm32::init(board::config());
    let board = board::take(p);
    #[cfg(feature = "usb")]
    let usb_parts = board.usb;
    let board::Board {
        outputs,
        buttons,
        mut led,
        iwdg,
        tick: tim7,
        link: uart,
        ..
    } = board;
    info!("sleeve: outputs at 0 A");
    // The buttons next: their tasks arm EXTI at their first poll (the yield), so a
    // press during the rest of the boot is posted, and latched (see `boot_events`).
    for (i, button) in buttons.into_iter().enumerate() {
        spawner.spawn(defmt::unwrap!(button_task(button, &tick::EDGES[i])));
    }
    Timer::after_millis(1).await;

    // The watchdog before anything that depends on flash contents: the boot check's
    // work is bounded (see `boot::check_bank`), and the boot timeout is above it.
    let mut dog = tick::Iwdg::start(iwdg);
    let source = bank_source(bank_region(), EMOJI_BANK);
    if core::ptr::eq(source, EMOJI_BANK) {
        info!("bank region erased: playing the built-in emoji bank");
    }
    let checked = check_bank(source);
    dog.feed();
    #[cfg(feature = "usb")]
    let (usb_link, usb_wire) = usb::split();
    let transports = link::Transports {
        uart,
        #[cfg(feature = "usb")]
        usb: usb_link,
    };
    let mut tick = start(spawner, source, checked, outputs, dog, tim7, transports);
    #[cfg(feature = "usb")]
    spawner.spawn(defmt::unwrap!(usb::run(usb_parts, usb_wire)));
    // Let the button tasks post what happened while the bank was checked.
    Timer::after_millis(1).await;
    let mut at_boot = heapless::Vec::<Report, BUTTONS>::new();
    for event in boot_events(board::BUTTON_MODE, &tick::EDGES) {
        if let Some(report) = tick.engine().inject(event) {
            let _ = at_boot.push(report);
        }
    }
    let mut reports = tick.start();
    if let Err(e) = checked {
        show_refused(&mut led, e).await
    }
    info!("ready: press to play slot 0, hold to select the next");
    // Ready: the selected slot's blinks (one, slot 0), then what presses during boot
    // did, like any other report (the tick runs, so the watchdog is fed meanwhile).
    let mut status = Led::new();
    status.show(Pattern::Selected(0), now_ms());
    for report in at_boot {
        info!("press during boot:");
        log(report);
        status.report(&report, now_ms());
    }
    // The LED's level until it changes or a report comes, whichever is first. Every
    // report goes through here, so the LED never misses one.
    loop {
        let light = status.at(now_ms());
        set(&mut led, light.on);
        let report = match light.until_ms {
            Some(t) => with_deadline(Instant::from_millis(t), reports.next())
                .await
                .ok(),
            None => Some(reports.next().await),
        };
        if let Some(report) = report {
            log(report);
            status.report(&report, now_ms());
        }
    }
}

/// Builds playback and starts the link: the controller over the checked bank, the
/// engine in its place for the tick (not started), the link's server in its task.
/// Not async, and not inlined into `run`: the engine and the server are built and
/// moved out here, so they take no room in `run`'s future (a static the size of
/// everything it holds across an await).
#[inline(never)]
fn start(
    spawner: Spawner,
    source: &'static [u8],
    checked: Result<touch_protocol::Bank<'static>, BootError>,
    outputs: outputs::Outputs,
    mut dog: tick::Iwdg,
    tim7: embassy_stm32::Peri<'static, embassy_stm32::peripherals::TIM7>,
    transports: link::Transports,
) -> tick::Tick {
    // A refused bank still boots the tick (every output at 0 A, nothing to play) and
    // the link, so that a computer can read why and upload a good bank.
    let mut controller = match checked {
        Ok(bank) => Controller::new(bank, device_config()),
        Err(e) => {
            error!("bank refused, nothing plays: {}", e);
            Controller::empty(device_config())
        }
    };
    info!("bank: {} slots", controller.slots());
    for i in 0..controller.slots() {
        match controller.slot(i) {
            Ok(s) => info!("  slot {}: {} ({} ms)", i, s.name(), s.duration_ms()),
            Err(e) => error!("  slot {}: refused, never played: {}", i, e),
        }
    }
    // The link's queues, split once: one end to the tick's controller, one to the
    // server's task.
    static mut CHANNELS: Channels = Channels::new();
    // SAFETY: `start` runs once (from `run`), so the queues are borrowed once, for good.
    let channels = unsafe { &mut *core::ptr::addr_of_mut!(CHANNELS) };
    let (link_port, tick_port) = channels.split();
    controller.attach(tick_port);
    let server = LinkServer::new(
        link_port,
        flash::BankFlash::new(),
        identity(source, EMOJI_BANK, checked),
    );
    dog.tighten();
    let engine = Engine::new(
        outputs,
        dog,
        Buttons::<BUTTONS>::new(board::BUTTON_MODE),
        controller,
    );
    let tick = tick::install(engine, tim7);
    spawner.spawn(defmt::unwrap!(link::serve(transports, server)));
    tick
}

fn now_ms() -> u64 {
    Instant::now().as_millis()
}

fn set(led: &mut Output<'static>, on: bool) {
    if on {
        led.set_high();
    } else {
        led.set_low();
    }
}

/// Logs a report (the tick interrupt never logs itself).
fn log(report: Report) {
    match report {
        Report::Fault(..) => warn!("limit hit, ramping to 0 A: {}", report),
        Report::BadSlot(slot, e) => error!("slot {}: refused, never played: {}", slot, e),
        Report::TooHot(slot, hot) => warn!(
            "slot {}: coil {} at {} per mille of its I2t budget, start refused; playable again after {} ms idle",
            slot, hot.channel, hot.permille, hot.cooldown_ms
        ),
        _ => info!("{}", report),
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

/// The refused bank's LED code (see `sleeve_firmware::led`), forever. The tick runs
/// (every output at 0 A, nothing to play) and feeds the watchdog; the link answers, so
/// a computer can read why and upload a good bank.
async fn show_refused(led: &mut Output<'static>, e: BootError) -> ! {
    let status = Led::refused(e, now_ms());
    loop {
        let light = status.at(now_ms());
        set(led, light.on);
        match light.until_ms {
            Some(t) => Timer::at(Instant::from_millis(t)).await,
            None => core::future::pending::<()>().await,
        }
    }
}

/// On panic: every channel to 0 A, say why, stop. The watchdog, no longer fed,
/// then resets the MCU, which boots with the outputs at 0 A and nothing playing.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    outputs::force_idle();
    log_panic(info);
    loop {
        cortex_m::asm::nop();
    }
}

/// Logs where the panic was, not its message (defmt cannot print core::fmt's
/// arguments without linking core::fmt's machinery). Reading anything of the panic's
/// info, the location too, keeps every panic site's location, message arguments and
/// formatters in flash: 9.7 KB of this firmware, which the default build has room for.
#[cfg(not(feature = "usb"))]
fn log_panic(info: &core::panic::PanicInfo) {
    match info.location() {
        Some(at) => error!("panic at {}:{}, outputs at 0 A", at.file(), at.line()),
        None => error!("panic, outputs at 0 A"),
    }
}

/// Logs the panic without its place: the USB build has no room for what reading the
/// panic's info keeps in flash (see the build without `usb`). Unread, the compiler
/// drops every panic site's location and message.
#[cfg(feature = "usb")]
fn log_panic(_info: &core::panic::PanicInfo) {
    error!("panic, outputs at 0 A");
}

/// On a hard fault (and the bus, memory and usage faults, which escalate to it while
/// they are disabled, as here): every channel to 0 A, then wait for the watchdog.
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    outputs::force_idle();
    loop {
        cortex_m::asm::nop();
    }
}

/// Every other exception and interrupt without a handler of its own (NMI, an
/// unexpected IRQ): every channel to 0 A, then wait for the watchdog, instead of
/// spinning with the outputs frozen at their last value.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(_irqn: i16) {
    cortex_m::interrupt::disable();
    outputs::force_idle();
    loop {
        cortex_m::asm::nop();
    }
}
