//! The per-section range checks [`Config::validate`] runs in the config's order.

use super::super::{
    grid_size, Config, MAX_TRAJECTORIES, MAX_TRANSFORMS, MAX_UPSAMPLE, PITCH_MM_RANGE,
    RATE_HZ_RANGE,
};
use super::{count, within, ConfigError, Knob, Unit};

impl Config {
    /// The `[input]` section: rate, pitch, tare, trim, baseline and touch threshold.
    pub(super) fn validate_input(&self) -> Result<(), ConfigError> {
        let i = &self.input;
        within(
            Knob::InputRateHz,
            i.rate_hz,
            *RATE_HZ_RANGE.start(),
            *RATE_HZ_RANGE.end(),
            Unit::Hz,
        )?;
        within(
            Knob::InputPitchMm,
            i.pitch_mm,
            *PITCH_MM_RANGE.start(),
            *PITCH_MM_RANGE.end(),
            Unit::Mm,
        )?;
        within(Knob::InputTareS, i.tare_s, 0.0, 60.0, Unit::S)?;
        within(Knob::InputTrimS, i.trim_s, 0.0, 60.0, Unit::S)?;
        within(
            Knob::InputBaselineQuantile,
            i.baseline_quantile,
            0.0,
            0.5,
            Unit::None,
        )?;
        within(
            Knob::InputTouchThresholdPsi,
            i.touch_threshold_psi,
            0.0,
            1e300,
            Unit::Psi,
        )?;
        Ok(())
    }

    /// The `[preprocess]` section: the upsampling and blur.
    pub(super) fn validate_preprocess(&self) -> Result<(), ConfigError> {
        let p = &self.preprocess;
        count(Knob::PreprocessUpsample, p.upsample, 1, MAX_UPSAMPLE)?;
        within(
            Knob::PreprocessBlurSigmaMm,
            p.blur_sigma_mm,
            0.01,
            500.0,
            Unit::Mm,
        )?;
        within(
            Knob::PreprocessBlurTruncate,
            p.blur_truncate,
            1.0,
            10.0,
            Unit::Sigmas,
        )?;
        Ok(())
    }

    /// The `[detect]` section: the contact thresholds and the plateau split.
    pub(super) fn validate_detect(&self) -> Result<(), ConfigError> {
        let d = &self.detect;
        // Thresholds bound no work; any finite scale of the data is a valid problem.
        within(
            Knob::DetectMinValuePsi,
            d.min_value_psi,
            0.0,
            1e300,
            Unit::Psi,
        )?;
        within(
            Knob::DetectSigmaK,
            d.sigma_k,
            -10.0,
            10.0,
            Unit::StandardDeviations,
        )?;
        within(
            Knob::DetectMaxProbability,
            d.max_probability,
            1e-6,
            0.999_999,
            Unit::None,
        )?;
        if let Some(split) = &d.split {
            within(Knob::DetectSplitLevel, split.level, 1e-6, 1.0, Unit::None)?;
            if let Some(extent) = split.extent {
                // The lattice reaches down from the top: an extent above the level
                // would shrink it below the top it is meant to cover.
                within(
                    Knob::DetectSplitExtent,
                    extent,
                    1e-6,
                    split.level,
                    Unit::None,
                )?;
            }
        }
        Ok(())
    }

    /// The `[track]` section: the link costs, speed gate and trajectory cap.
    pub(super) fn validate_track(&self) -> Result<(), ConfigError> {
        let t = &self.track;
        within(Knob::TrackEntryCost, t.entry_cost, 0.0, 1000.0, Unit::None)?;
        within(Knob::TrackExitCost, t.exit_cost, 0.0, 1000.0, Unit::None)?;
        within(
            Knob::TrackMaxSpeedMmS,
            t.max_speed_mm_s,
            1.0,
            20_000.0,
            Unit::MmPerS,
        )?;
        count(
            Knob::TrackMaxTrajectories,
            t.max_trajectories,
            1,
            MAX_TRAJECTORIES,
        )?;
        Ok(())
    }

    /// The `[placement]` section: the transform grid and its coarse-to-fine search.
    pub(super) fn validate_placement(&self) -> Result<(), ConfigError> {
        let pl = &self.placement;
        count(Knob::PlacementGridX, pl.grid_x, 1, MAX_TRANSFORMS)?;
        count(Knob::PlacementGridY, pl.grid_y, 1, MAX_TRANSFORMS)?;
        if grid_size(pl).is_none_or(|n| n > MAX_TRANSFORMS) {
            return Err(ConfigError::TooManyTransforms {
                grid_x: pl.grid_x,
                grid_y: pl.grid_y,
                max: MAX_TRANSFORMS,
            });
        }
        within(
            Knob::PlacementCentreBonus,
            pl.centre_bonus,
            0.0,
            10.0,
            Unit::None,
        )?;
        if let Some(c) = &pl.coarse_to_fine {
            count(Knob::PlacementCoarseToFineStride, c.stride, 1, 1000)?;
            count(Knob::PlacementCoarseToFineKeep, c.keep, 1, MAX_TRANSFORMS)?;
        }
        Ok(())
    }

    /// The `[crop]` section: the time and space margins.
    pub(super) fn validate_crop(&self) -> Result<(), ConfigError> {
        let c = &self.crop;
        within(Knob::CropTimeMarginS, c.time_margin_s, 0.0, 60.0, Unit::S)?;
        within(
            Knob::CropSpaceMarginMm,
            c.space_margin_mm,
            0.0,
            10_000.0,
            Unit::Mm,
        )?;
        Ok(())
    }

    /// The `[signal]` section: the spike filter, low-pass and drive waveform.
    pub(super) fn validate_signal(&self) -> Result<(), ConfigError> {
        let s = &self.signal;
        within(
            Knob::SignalSpikeFraction,
            s.spike_fraction,
            0.0,
            1.0,
            Unit::None,
        )?;
        count(Knob::SignalLowpassOrder, s.lowpass_order, 1, 16)?;
        within(Knob::SignalLowpassHz, s.lowpass_hz, 0.01, 500.0, Unit::Hz)?;
        within(Knob::SignalPreDentA, s.pre_dent_a, -1.0, 1.0, Unit::A)?;
        within(Knob::SignalPeakA, s.peak_a, -1.0, 1.0, Unit::A)?;
        within(Knob::SignalRampS, s.ramp_s, 0.0, 60.0, Unit::S)?;
        within(
            Knob::SignalFitThermalShare,
            s.fit_thermal_share,
            0.01,
            1.0,
            Unit::None,
        )?;
        Ok(())
    }

    /// The `[keyframes]` section: the error bounds, ramp, periods and quantisation.
    pub(super) fn validate_keyframes(&self) -> Result<(), ConfigError> {
        let k = &self.keyframes;
        within(
            Knob::KeyframesMaxRmsErrorFs,
            k.max_rms_error_fs,
            1e-6,
            1.0,
            Unit::FullScale,
        )?;
        within(
            Knob::KeyframesMaxAbsErrorFs,
            k.max_abs_error_fs,
            1e-6,
            1.0,
            Unit::FullScale,
        )?;
        count(Knob::KeyframesRampMs, usize::from(k.ramp_ms), 0, 10_000)?;
        within(
            Knob::KeyframesAllocateAboveBytesPerS,
            k.allocate_above_bytes_per_s,
            0.0,
            1e9,
            Unit::BytesPerS,
        )?;
        if !(1..=1000).contains(&k.periods_ms.len()) {
            return Err(ConfigError::LengthOutOfRange {
                knob: Knob::KeyframesPeriodsMs,
                len: k.periods_ms.len(),
                min: 1,
                max: 1000,
            });
        }
        for &p in &k.periods_ms {
            count(Knob::KeyframesPeriodsMs, usize::from(p), 1, 1000)?;
        }
        count(
            Knob::KeyframesMaxQuantShift,
            usize::from(k.max_quant_shift),
            0,
            15,
        )?;
        Ok(())
    }
}
