//! The output stage: eight 12-bit channels on TIM3/TIM4 PWM, optionally channels 0-1
//! on the DAC. Implements the player's [`OutputSink`].

use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals;
use embassy_stm32::peripherals::{TIM3, TIM4};
use embassy_stm32::timer::simple_pwm::SimplePwm;
use sleeve_firmware::output::{pwm_compare, Frame, PWM_PERIOD};
use touch_protocol::{OutputSink, IDLE_CODE};

/// The eight channels. Writing a frame loads the compare registers; with preload on,
/// all eight take the new values at the same carrier boundary (the two timers run
/// in lock-step, TIM4 started by TIM3's enable).
pub struct Outputs {
    _tim3: SimplePwm<'static, TIM3>,
    _tim4: SimplePwm<'static, TIM4>,
    #[cfg(feature = "dac-outputs")]
    dac: embassy_stm32::dac::Dac<'static, embassy_stm32::mode::Blocking>,
}

const TIMERS: [pac::timer::TimGp16; 2] = [pac::TIM3, pac::TIM4];

impl Outputs {
    /// Takes the two PWM timers (pins already in alternate function mode), sets every
    /// channel to 0 A, then starts both timers together.
    pub fn new(
        tim3: SimplePwm<'static, TIM3>,
        tim4: SimplePwm<'static, TIM4>,
        #[cfg(feature = "dac-outputs")] dac: embassy_stm32::dac::Dac<
            'static,
            embassy_stm32::mode::Blocking,
        >,
    ) -> Self {
        for t in TIMERS {
            t.cr1().modify(|w| w.set_cen(false));
            t.psc().write_value(0);
            t.arr().write(|w| w.set_arr((PWM_PERIOD - 1) as u16));
            t.cnt().write(|w| w.set_cnt(0));
            for c in 0..4 {
                t.ccr(c)
                    .write(|w| w.set_ccr(pwm_compare(IDLE_CODE, PWM_PERIOD) as u16));
            }
            // Load the preloaded period and compare values before any pin drives.
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
        #[cfg_attr(not(feature = "dac-outputs"), allow(unused_mut))]
        let mut outputs = Outputs {
            _tim3: tim3,
            _tim4: tim4,
            #[cfg(feature = "dac-outputs")]
            dac,
        };
        outputs.write(&[IDLE_CODE; touch_protocol::CHANNELS]);
        outputs
    }
}

impl OutputSink for Outputs {
    fn write(&mut self, codes: &Frame) {
        for (c, &code) in codes.iter().enumerate() {
            TIMERS[c / 4]
                .ccr(c % 4)
                .write(|w| w.set_ccr(pwm_compare(code, PWM_PERIOD) as u16));
        }
        #[cfg(feature = "dac-outputs")]
        {
            use sleeve_firmware::output::dac_value;
            self.dac.set(embassy_stm32::dac::DualValue::Bit12Right(
                dac_value(codes[0]),
                dac_value(codes[1]),
            ));
        }
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
    pac::DAC1.dhr12rd().write(|w| {
        w.set_dhr(0, IDLE_CODE);
        w.set_dhr(1, IDLE_CODE);
    });
}
