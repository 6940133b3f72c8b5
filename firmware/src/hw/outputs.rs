//! The output stage: eight 12-bit channels on TIM3/TIM4 PWM, optionally channels 0-1
//! on the DAC. Implements the player's [`OutputSink`].
//!
//! Configured register by register (not through the HAL's PWM driver) for one
//! reason: the order. Timers are set to 0 A (50 % duty) and running before any pin
//! is switched to them; until then the pins are inputs, as at reset.
//!
//! Which pins those are is the board's (`board.rs`, the pin table), handed in as
//! [`Pins`]: this stage owns the order, not the wiring.

use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::{Moder, Ospeedr};
use embassy_stm32::pac::timer::vals;
use embassy_stm32::peripherals::{TIM3, TIM4};
use embassy_stm32::Peri;
use sleeve_firmware::output::{pwm_compare, Frame, PWM_PERIOD};
use touch_protocol::{OutputSink, IDLE_CODE};

/// A pin the output stage drives, switched to its timer or the DAC by register.
#[derive(Clone, Copy)]
pub struct OutputPin {
    /// GPIO port.
    pub port: pac::gpio::Gpio,
    /// Pin number in the port.
    pub pin: usize,
}

/// Where the channels come out: the board's pins for this stage.
pub struct Pins {
    /// The PWM pins in use, in channel order (TIM3 CH1-CH4, then TIM4 CH1-CH4; with
    /// `dac-outputs`, from TIM3 CH3 on).
    pub pwm: &'static [OutputPin],
    /// The alternate function that connects every PWM pin to its timer.
    pub pwm_af: u8,
    /// The pins of DAC OUT1 and OUT2 (channels 0 and 1).
    #[cfg(feature = "dac-outputs")]
    pub dac: &'static [OutputPin],
}

/// The eight channels. Writing a frame loads the compare registers; with preload on,
/// all eight take the new values at the same carrier boundary (the two timers run
/// in lock-step, TIM4 started by TIM3's enable).
pub struct Outputs {
    _tim3: Peri<'static, TIM3>,
    _tim4: Peri<'static, TIM4>,
}

const TIMERS: [pac::timer::TimGp16; 2] = [pac::TIM3, pac::TIM4];

impl Outputs {
    /// Sets every channel to 0 A, starts both timers together, then connects the
    /// PWM pins of `pins` (and, with `dac-outputs`, the DAC pins).
    pub fn new(tim3: Peri<'static, TIM3>, tim4: Peri<'static, TIM4>, pins: &Pins) -> Self {
        embassy_stm32::rcc::enable_and_reset::<TIM3>();
        embassy_stm32::rcc::enable_and_reset::<TIM4>();
        for t in TIMERS {
            t.psc().write_value(0);
            t.arr().write(|w| w.set_arr((PWM_PERIOD - 1) as u16));
            t.cr1().modify(|w| w.set_arpe(true));
            for c in 0..4 {
                t.ccmr_output(c / 2).modify(|w| {
                    w.set_ocm(c % 2, vals::Ocm::PWM_MODE1);
                    w.set_ocpe(c % 2, true);
                });
                t.ccr(c)
                    .write(|w| w.set_ccr(pwm_compare(IDLE_CODE, PWM_PERIOD) as u16));
            }
            // Load the preloaded period and compare values.
            t.egr().write(|w| w.set_ug(true));
            t.ccer().modify(|w| {
                for c in 0..4 {
                    w.set_cce(c, true);
                }
            });
        }
        // TIM3's enable is TIM4's start trigger (ITR2): both count from 0 together.
        pac::TIM3.cr2().modify(|w| w.set_mms(vals::Mms::ENABLE));
        pac::TIM4.smcr().modify(|w| {
            w.set_ts(vals::Ts::ITR2);
            w.set_sms(vals::Sms::TRIGGER_MODE);
        });
        pac::TIM3.cr1().modify(|w| w.set_cen(true));

        #[cfg(feature = "dac-outputs")]
        dac_init(pins.dac);
        for &OutputPin { port, pin } in pins.pwm.iter() {
            port.afr(pin / 8)
                .modify(|w| w.set_afr(pin % 8, pins.pwm_af));
            port.ospeedr()
                .modify(|w| w.set_ospeedr(pin, Ospeedr::MEDIUM_SPEED));
            port.moder().modify(|w| w.set_moder(pin, Moder::ALTERNATE));
        }
        Outputs {
            _tim3: tim3,
            _tim4: tim4,
        }
    }
}

/// DAC channels 1-2 at mid-scale, then enabled, then connected to their pins.
#[cfg(feature = "dac-outputs")]
fn dac_init(pins: &[OutputPin]) {
    embassy_stm32::rcc::enable_and_reset::<embassy_stm32::peripherals::DAC1>();
    write_dac(IDLE_CODE, IDLE_CODE);
    pac::DAC1.cr().modify(|w| {
        w.set_en(0, true);
        w.set_en(1, true);
    });
    write_dac(IDLE_CODE, IDLE_CODE);
    for &OutputPin { port, pin } in pins.iter() {
        port.moder().modify(|w| w.set_moder(pin, Moder::ANALOG));
    }
}

/// Both DAC channels at once (dual 12-bit right-aligned register).
#[cfg(feature = "dac-outputs")]
fn write_dac(ch0: u16, ch1: u16) {
    use sleeve_firmware::output::dac_value;
    pac::DAC1.dhr12rd().write(|w| {
        w.set_dhr(0, dac_value(ch0));
        w.set_dhr(1, dac_value(ch1));
    });
}

impl OutputSink for Outputs {
    fn write(&mut self, codes: &Frame) {
        for (c, &code) in codes.iter().enumerate() {
            TIMERS[c / 4]
                .ccr(c % 4)
                .write(|w| w.set_ccr(pwm_compare(code, PWM_PERIOD) as u16));
        }
        #[cfg(feature = "dac-outputs")]
        write_dac(codes[0], codes[1]);
    }
}

/// Drives every channel to 0 A without owning the peripherals: for the panic and
/// fault handlers, when nothing else may run.
pub fn force_idle() {
    let idle = pwm_compare(IDLE_CODE, PWM_PERIOD) as u16;
    for t in TIMERS {
        for c in 0..4 {
            t.ccr(c).write(|w| w.set_ccr(idle));
        }
    }
    #[cfg(feature = "dac-outputs")]
    write_dac(IDLE_CODE, IDLE_CODE);
}
