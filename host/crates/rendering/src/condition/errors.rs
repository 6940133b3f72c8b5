//! Why conditioning refuses its input.

use thiserror::Error;

/// Why conditioning refused its input; the variant names the parameter or sample at fault.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum ConditionError {
    /// The low-pass cannot be designed: order outside 1..=16, or a cut-off not strictly
    /// between 0 and the Nyquist frequency.
    #[error(
        "low-pass order {order} at {cutoff_hz} Hz is not realisable at {rate_hz} Hz \
         (order 1..=16, 0 < cut-off < rate / 2)"
    )]
    InvalidFilter {
        /// Requested order.
        order: usize,
        /// Requested cut-off, Hz.
        cutoff_hz: f64,
        /// Sampling rate, Hz.
        rate_hz: f64,
    },
    /// A scalar parameter is out of its domain (negative, NaN or infinite).
    #[error("signal parameter `{name}` = {} is out of range", touchc_model::display::Shortest(*.value))]
    InvalidParameter {
        /// Config field name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// `pre_dent_a` must lie strictly below `peak_a`, both finite.
    #[error("pre-dent {pre_dent_a} A must be below the peak {peak_a} A")]
    InvalidRange {
        /// Resting current, A.
        pre_dent_a: f64,
        /// Peak current, A.
        peak_a: f64,
    },
    /// Channels must all have the same number of frames.
    #[error("channel {channel} has {len} frames, channel 0 has {expected}")]
    LengthMismatch {
        /// Offending channel.
        channel: usize,
        /// Its length.
        len: usize,
        /// Length of channel 0.
        expected: usize,
    },
    /// A pressure sample is NaN or infinite.
    #[error("pressure at channel {channel}, frame {frame} is not finite")]
    NotFinite {
        /// Channel of the sample.
        channel: usize,
        /// Frame of the sample.
        frame: usize,
    },
}
