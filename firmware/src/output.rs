//! Output scaling and the firmware's hard limits.

use touch_protocol::player::MAX_CODE;
use touch_protocol::{DeviceConfig, Limits, CHANNELS, IDLE_CODE};

/// One frame: a 12-bit code per channel, 2048 = 0 A.
pub type Frame = [u16; CHANNELS];

/// Every channel at 0 A.
pub const IDLE_FRAME: Frame = [IDLE_CODE; CHANNELS];

/// PWM counter period: 4096 counts at the 84 MHz timer clock (20.5 kHz carrier), so a
/// 12-bit code is its own compare value.
pub const PWM_PERIOD: u32 = 4096;

/// Current at codes 0 and 4095: the LM675T stage has a gain of 1 A/V.
pub const FULL_SCALE_MA: u16 = 1000;

/// Geometry hash of the actuator layout this firmware drives: a bank compiled for
/// another is refused at boot, and a slot for another never plays.
pub const LAYOUT_HASH: u32 = touch_protocol::layout::SLEEVE_HASH;

/// Limits compiled into the firmware: the sleeve's, as the protocol crate defines them
/// (one source for the host's checks and the device's). The stimulus carries its own;
/// the player enforces the stricter of the two on every tick, so a bank compiled for a
/// bolder device cannot exceed these.
pub const HARD_LIMITS: Limits = Limits::SLEEVE;

/// The device as the player sees it: full scale and the hard limits.
pub const fn device_config() -> DeviceConfig {
    DeviceConfig {
        full_scale_ma: FULL_SCALE_MA,
        limits: HARD_LIMITS,
    }
}

/// Compare value for `code` on a timer whose period is `period` counts.
///
/// Codes above 4095 (never produced by the player) saturate; 2048 maps to exactly
/// half the period, so 0 A is a 50 % duty cycle on any period.
pub const fn pwm_compare(code: u16, period: u32) -> u32 {
    let code = if code > MAX_CODE { MAX_CODE } else { code };
    (code as u32 * period) / 4096
}

/// DAC data register value (12-bit right-aligned) for `code`.
pub const fn dac_value(code: u16) -> u16 {
    if code > MAX_CODE {
        MAX_CODE
    } else {
        code
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn idle_is_half_duty() {
        assert_eq!(pwm_compare(IDLE_CODE, PWM_PERIOD), PWM_PERIOD / 2);
        assert_eq!(pwm_compare(IDLE_CODE, 1000), 500);
        assert_eq!(dac_value(IDLE_CODE), 2048);
    }

    #[test]
    fn hard_limits_never_looser_than_the_sleeve() {
        let d = device_config();
        assert_eq!(d.limits, d.limits.min(Limits::SLEEVE));
        assert_eq!(d.limits, d.limits.min(HARD_LIMITS));
    }

    proptest! {
        #[test]
        fn compare_is_identity_at_12_bit_and_monotone(a in 0u16..=u16::MAX, b in 0u16..=u16::MAX, period in 1u32..=65536) {
            if a <= MAX_CODE {
                prop_assert_eq!(pwm_compare(a, PWM_PERIOD), u32::from(a));
            }
            prop_assert!(pwm_compare(a, period) < period);
            if a <= b {
                prop_assert!(pwm_compare(a, period) <= pwm_compare(b, period));
            }
            prop_assert!(dac_value(a) <= MAX_CODE);
        }
    }
}
