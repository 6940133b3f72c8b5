//! The 1 kHz tick: TIM7's update interrupt steps the [`Engine`].

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{IWDG, TIM7};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{interrupt, pac, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
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

/// What the tick reports, for the log task. Full means dropped, never blocked.
pub static REPORTS: Channel<CriticalSectionRawMutex, Report, 16> = Channel::new();

/// The engine in its place for the tick, before the tick runs.
pub struct Tick {
    engine: &'static mut SleeveEngine,
    _tim7: Peri<'static, TIM7>,
}

/// Puts the engine where the tick interrupt will own it (it is not moved again).
pub fn install(engine: SleeveEngine, tim7: Peri<'static, TIM7>) -> Tick {
    // SAFETY: `install` runs once (it takes the TIM7 singleton), and the interrupt
    // that reads ENGINE is enabled only by `Tick::start`, which gives up this borrow.
    let engine = unsafe { (*addr_of_mut!(ENGINE)).write(engine) };
    Tick {
        engine,
        _tim7: tim7,
    }
}

impl Tick {
    /// The engine, until the tick starts.
    pub fn engine(&mut self) -> &mut SleeveEngine {
        self.engine
    }

    /// Hands the engine to the tick interrupt and starts TIM7 at 1 kHz.
    pub fn start(self) {
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
        // SAFETY: the handler below only touches ENGINE (written by `install`, its
        // borrow given up with `self`), the mailboxes and the report channel, all of
        // which are ready.
        unsafe { interrupt::TIM7.enable() };
        t.cr1().modify(|w| w.set_cen(true));
    }
}

#[interrupt]
fn TIM7() {
    pac::TIM7.sr().write(|w| w.set_uif(false));
    // SAFETY: this interrupt is enabled only after `install` wrote ENGINE, and from
    // then on only this handler touches it. At the highest priority nothing preempts
    // it to run it again (an interrupt does not preempt one of its own priority).
    let engine = unsafe { (*addr_of_mut!(ENGINE)).assume_init_mut() };
    let edges = core::array::from_fn(|i| EDGES[i].take());
    engine.tick(edges, |report| {
        let _ = REPORTS.try_send(report);
    });
    if engine.controller().link_answered() {
        super::link::wake_from_tick();
    }
}
