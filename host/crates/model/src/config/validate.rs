//! Every knob's range, checked before any stage runs.
//!
//! A range says what makes physical sense (positive, finite, below a cap that a real
//! sleeve or sensor never needs) and, with [`Config::validate_for`], bounds the work the
//! derived pixel and frame values ask for: the blur kernel, the upsampled frame, the link
//! gate, the filter. Outside a range the compile stops with the knob's name, the value
//! and the range, instead of running for minutes, allocating gigabytes or panicking in a
//! third-party routine.

use super::{
    grid_size, Config, Sampling, MAX_TRANSFORMS, MAX_UPSAMPLE, PITCH_MM_RANGE, RATE_HZ_RANGE,
};

/// A knob outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The value itself is outside the knob's range.
    #[error("{knob} = {value} is out of range: must be {range}")]
    OutOfRange {
        /// The knob, as `section.key`.
        knob: &'static str,
        /// The value given.
        value: String,
        /// The accepted range, with its unit.
        range: String,
    },
    /// The value is in range, but what it becomes at this recording's sampling is not.
    #[error("{knob} = {value} is {derived} at {sampling}: must be {range}")]
    Derived {
        /// The knob, as `section.key`.
        knob: &'static str,
        /// The value given.
        value: String,
        /// What it becomes in pixels or frames.
        derived: String,
        /// The sampling it was derived at.
        sampling: String,
        /// The accepted range of the derived value.
        range: String,
    },
}

/// Largest blur kernel radius, pixels: a 2,049-tap kernel (the paper's is 25).
pub(crate) const MAX_KERNEL_RADIUS_PX: f64 = 1024.0;
/// Largest upsampled frame, pixels per side.
pub(crate) const MAX_FRAME_PX: usize = 4096;
/// Largest link gate radius, pixels per frame (a gate wider than the frame links
/// everything anyway).
pub(crate) const MAX_GATE_PX: f64 = 4096.0;

/// `v` as a user typed it: `1e308` and `5e-324` in exponent form rather than 300 digits.
fn num(v: f64) -> String {
    crate::display::Shortest(v).to_string()
}

/// `knob` must be finite and within `[lo, hi]` (in `unit`).
fn within(knob: &'static str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), ConfigError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        return Ok(());
    }
    Err(ConfigError::OutOfRange {
        knob,
        value: num(v),
        range: format!("finite, in [{}, {}]{unit}", num(lo), num(hi)),
    })
}

/// `knob` must be within `[lo, hi]`.
fn count(knob: &'static str, v: usize, lo: usize, hi: usize) -> Result<(), ConfigError> {
    if (lo..=hi).contains(&v) {
        return Ok(());
    }
    Err(ConfigError::OutOfRange {
        knob,
        value: v.to_string(),
        range: format!("in [{lo}, {hi}]"),
    })
}

impl Config {
    /// Checks every knob against its range (see the module docs); the first one out of
    /// range is the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let i = &self.input;
        within(
            "input.rate_hz",
            i.rate_hz,
            *RATE_HZ_RANGE.start(),
            *RATE_HZ_RANGE.end(),
            " Hz",
        )?;
        within(
            "input.pitch_mm",
            i.pitch_mm,
            *PITCH_MM_RANGE.start(),
            *PITCH_MM_RANGE.end(),
            " mm",
        )?;
        within("input.tare_s", i.tare_s, 0.0, 60.0, " s")?;
        within("input.trim_s", i.trim_s, 0.0, 60.0, " s")?;
        within("input.baseline_quantile", i.baseline_quantile, 0.0, 0.5, "")?;
        within(
            "input.touch_threshold_psi",
            i.touch_threshold_psi,
            0.0,
            1e300,
            " psi",
        )?;
        let p = &self.preprocess;
        count("preprocess.upsample", p.upsample, 1, MAX_UPSAMPLE)?;
        within(
            "preprocess.blur_sigma_mm",
            p.blur_sigma_mm,
            0.01,
            500.0,
            " mm",
        )?;
        within(
            "preprocess.blur_truncate",
            p.blur_truncate,
            1.0,
            10.0,
            " sigmas",
        )?;
        let d = &self.detect;
        // Thresholds bound no work; any finite scale of the data is a valid problem.
        within("detect.min_value_psi", d.min_value_psi, 0.0, 1e300, " psi")?;
        within(
            "detect.sigma_k",
            d.sigma_k,
            -10.0,
            10.0,
            " standard deviations",
        )?;
        within(
            "detect.max_probability",
            d.max_probability,
            1e-6,
            0.999_999,
            "",
        )?;
        let t = &self.track;
        within("track.entry_cost", t.entry_cost, 0.0, 1000.0, "")?;
        within("track.exit_cost", t.exit_cost, 0.0, 1000.0, "")?;
        within(
            "track.max_speed_mm_s",
            t.max_speed_mm_s,
            1.0,
            20_000.0,
            " mm/s",
        )?;
        count(
            "track.max_trajectories",
            t.max_trajectories,
            1,
            super::MAX_TRAJECTORIES,
        )?;
        let pl = &self.placement;
        count("placement.grid_x", pl.grid_x, 1, MAX_TRANSFORMS)?;
        count("placement.grid_y", pl.grid_y, 1, MAX_TRANSFORMS)?;
        if grid_size(pl).is_none_or(|n| n > MAX_TRANSFORMS) {
            return Err(ConfigError::OutOfRange {
                knob: "placement.grid_x * grid_y * (grid_y + 1) / 2",
                value: format!("{} x {}", pl.grid_x, pl.grid_y),
                range: format!("at most {MAX_TRANSFORMS} transforms"),
            });
        }
        within("placement.centre_bonus", pl.centre_bonus, 0.0, 10.0, "")?;
        if let Some(c) = &pl.coarse_to_fine {
            count("placement.coarse_to_fine.stride", c.stride, 1, 1000)?;
            count("placement.coarse_to_fine.keep", c.keep, 1, MAX_TRANSFORMS)?;
        }
        let c = &self.crop;
        within("crop.time_margin_s", c.time_margin_s, 0.0, 60.0, " s")?;
        within(
            "crop.space_margin_mm",
            c.space_margin_mm,
            0.0,
            10_000.0,
            " mm",
        )?;
        let s = &self.signal;
        within("signal.spike_fraction", s.spike_fraction, 0.0, 1.0, "")?;
        count("signal.lowpass_order", s.lowpass_order, 1, 16)?;
        within("signal.lowpass_hz", s.lowpass_hz, 0.01, 500.0, " Hz")?;
        within("signal.pre_dent_a", s.pre_dent_a, -1.0, 1.0, " A")?;
        within("signal.peak_a", s.peak_a, -1.0, 1.0, " A")?;
        within("signal.ramp_s", s.ramp_s, 0.0, 60.0, " s")?;
        within(
            "signal.fit_thermal_share",
            s.fit_thermal_share,
            0.01,
            1.0,
            "",
        )?;
        let k = &self.keyframes;
        within(
            "keyframes.max_rms_error_fs",
            k.max_rms_error_fs,
            1e-6,
            1.0,
            " of full scale",
        )?;
        within(
            "keyframes.max_abs_error_fs",
            k.max_abs_error_fs,
            1e-6,
            1.0,
            " of full scale",
        )?;
        count("keyframes.ramp_ms", usize::from(k.ramp_ms), 0, 10_000)?;
        within(
            "keyframes.allocate_above_bytes_per_s",
            k.allocate_above_bytes_per_s,
            0.0,
            1e9,
            " B/s",
        )?;
        count("keyframes.periods_ms (count)", k.periods_ms.len(), 1, 1000)?;
        for &p in &k.periods_ms {
            count("keyframes.periods_ms", usize::from(p), 1, 1000)?;
        }
        count(
            "keyframes.max_quant_shift",
            usize::from(k.max_quant_shift),
            0,
            15,
        )?;
        Ok(())
    }

    /// [`Config::validate`], then the values derived at `sampling` for a recording of
    /// `rows x cols` cells: the rate and pitch themselves, the blur kernel, the
    /// upsampled frame, the link gate and the low-pass against the Nyquist frequency.
    pub fn validate_for(
        &self,
        sampling: &Sampling,
        (rows, cols): (usize, usize),
    ) -> Result<(), ConfigError> {
        self.validate()?;
        // The same ranges a file's own metadata must meet (one source for each fact).
        within(
            "rate_hz (--rate)",
            sampling.rate_hz,
            *RATE_HZ_RANGE.start(),
            *RATE_HZ_RANGE.end(),
            " Hz",
        )?;
        within(
            "pitch_mm (--pitch-mm)",
            sampling.pitch_mm,
            *PITCH_MM_RANGE.start(),
            *PITCH_MM_RANGE.end(),
            " mm",
        )?;
        let at = format!(
            "{} Hz, {} mm cells, x{}",
            sampling.rate_hz, sampling.pitch_mm, sampling.upsample
        );
        let derived = |knob, value: f64, derived: String, range: String| ConfigError::Derived {
            knob,
            value: num(value),
            derived,
            sampling: at.clone(),
            range,
        };
        let p = &self.preprocess;
        // scipy's kernel radius, as the blur computes it.
        let radius = (p.blur_truncate * sampling.px(p.blur_sigma_mm) + 0.5).floor();
        // A kernel that does not reach half an upsampled cell leaves pixels that see only
        // their own cell: the cell's flat top survives the blur, every pixel of it is a
        // local maximum, and the flow solver drowns in detections (minutes, gigabytes).
        let min_radius = (p.upsample as f64 / 2.0).ceil();
        if radius < min_radius {
            return Err(derived(
                "preprocess.blur_sigma_mm",
                p.blur_sigma_mm,
                format!(
                    "a kernel radius of {radius} px (truncate {})",
                    p.blur_truncate
                ),
                format!("at least {min_radius} px, half an upsampled cell"),
            ));
        }
        if radius > MAX_KERNEL_RADIUS_PX {
            return Err(derived(
                "preprocess.blur_sigma_mm",
                p.blur_sigma_mm,
                format!("a kernel radius of {radius:.0} px"),
                format!("at most {MAX_KERNEL_RADIUS_PX} px"),
            ));
        }
        let side = rows.max(cols).saturating_mul(p.upsample);
        if side > MAX_FRAME_PX {
            return Err(derived(
                "preprocess.upsample",
                p.upsample as f64,
                format!("{side} px along the longer side of {rows} x {cols} cells"),
                format!("at most {MAX_FRAME_PX} px"),
            ));
        }
        let gate = sampling.gate_px2(self.track.max_speed_mm_s).sqrt();
        if gate > MAX_GATE_PX {
            return Err(derived(
                "track.max_speed_mm_s",
                self.track.max_speed_mm_s,
                format!("{gate:.0} px per frame"),
                format!("at most {MAX_GATE_PX} px"),
            ));
        }
        let nyquist = sampling.rate_hz / 2.0;
        if self.signal.lowpass_hz >= nyquist {
            return Err(derived(
                "signal.lowpass_hz",
                self.signal.lowpass_hz,
                "the low-pass cut-off".into(),
                format!("below the Nyquist frequency, {nyquist} Hz"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_is_valid() {
        for p in crate::config::Preset::ALL {
            let c = Config::preset(p);
            c.validate_for(&Sampling::PAPER, (8, 21)).unwrap();
        }
    }

    #[test]
    fn the_error_names_knob_value_and_range() {
        let mut c = Config::default();
        c.detect.sigma_k = f64::NAN;
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("detect.sigma_k = NaN") && e.contains("[-10, 10]"),
            "{e}"
        );
        let mut c = Config::default();
        c.signal.lowpass_hz = 10.0;
        let e = c
            .validate_for(&Sampling::PAPER, (8, 21))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("signal.lowpass_hz = 10") && e.contains("10 Hz"),
            "{e}"
        );
    }
}
