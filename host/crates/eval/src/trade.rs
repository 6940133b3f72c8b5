//! The speed/accuracy trade, measured: every [`Preset`] compiled on one recording and
//! compared with `exact` (`touchc trade`, `docs/trade.md`).
//!
//! The comparisons are on what reaches the skin or decides it, not on intermediate
//! numbers that mean different things under different presets:
//! - the placement score (same units under every preset: summed detection costs times
//!   workspace weights), as a gap relative to `exact`'s;
//! - the compiled f64 1 kHz signal, RMS difference to `exact`'s in % of full scale (both
//!   come from the same tared recording, so sample `i` is the same instant in both);
//! - the trajectories: the share of detections that both runs track, matched per frame
//!   by position in mm (the presets may sample the frame on different pixel grids);
//! - time per stage and the file size.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::evaluate::evaluate_compiled;
use touch_protocol::CHANNELS;
use touchc_encoding::keyframes::KeyframeOptions;
use touchc_input::recording::Recording;
use touchc_model::config::{ConfigError, Layers, OffTable, Preset, ValidConfig};
use touchc_model::geometry::pixel_centre_mm;
use touchc_model::stage::{Stage, StageSeconds};
use touchc_pipeline::compile::{compile, CompileError, CompileOptions, Compiled};
use touchc_synth::Truth;
use touchc_tracking::track::TrackOutput;

/// One preset's row of the trade table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeRow {
    /// The recording's name.
    pub input: String,
    /// The preset.
    pub preset: Preset,
    /// Wall seconds per stage and `total` (the fastest of the repeats).
    pub seconds: StageSeconds,
    /// Transforms scored (met a trajectory) and in the grid.
    pub transforms: (usize, usize),
    /// Placement score (lower is better).
    pub score: f64,
    /// `(score - exact) / |exact|`, percent; 0 when both are 0. Positive = worse.
    pub score_gap_pct: f64,
    /// RMS difference of the 1 kHz signal to `exact`'s, percent of full scale.
    pub rms_vs_exact_pct: f64,
    /// Largest such difference, percent of full scale.
    pub max_vs_exact_pct: f64,
    /// Detections tracked by both this preset and `exact`, percent of the larger count.
    pub tracks_agree_pct: f64,
    /// Stimulus file size.
    pub bytes: usize,
    /// Share of the touch pressure within two cells of a tracked contact.
    pub coverage: f64,
    /// Share of the touch pressure a driven actuator plays, within its workspace.
    pub rendered: f64,
    /// Share of the true contacts tracked (`None` without a truth file).
    pub recall: Option<f64>,
}

/// `presets`, each with its config: `layers` over it (`touchc trade`'s `--config`,
/// `--set` and knob flags). The preset `asked` takes every layer; the others (the
/// `exact` reference among them) take the assignments their tables have, and the ones
/// left out are returned with their preset, so one set of overrides means the same
/// under every preset it can apply to.
#[allow(clippy::type_complexity)]
pub fn configs(
    layers: &Layers,
    presets: &[Preset],
    asked: Option<Preset>,
) -> Result<(Vec<(Preset, ValidConfig)>, Vec<(Preset, OffTable)>), ConfigError> {
    let mut configs = Vec::new();
    let mut skipped = Vec::new();
    for &p in presets {
        let on = layers.clone().on(p);
        let config = if asked == Some(p) {
            on.build()?
        } else {
            let (kept, off) = on.where_it_applies();
            skipped.extend(off.into_iter().map(|t| (p, t)));
            kept.build()?
        };
        configs.push((p, config));
    }
    Ok((configs, skipped))
}

/// Compiles `rec` under every preset of `configs` with its config (each `repeats`
/// times, keeping the fastest) and compares each with the `exact` entry; no rows
/// without one. `base` supplies everything but the config. With the `truth` of a
/// synthetic recording (`touchc synth --truth`), each row also gets its recall.
///
/// `configs` is usually [`Preset::ALL`] with [`ValidConfig::preset`], or [`configs`]
/// with overrides laid over each preset.
pub fn trade(
    rec: &Recording,
    base: &CompileOptions,
    configs: &[(Preset, ValidConfig)],
    repeats: usize,
    truth: Option<&Truth>,
) -> Result<Vec<TradeRow>, CompileError> {
    let mut runs = Vec::new();
    for (preset, config) in configs {
        let preset = *preset;
        let opts = CompileOptions {
            config: config.clone(),
            ..base.clone()
        };
        let mut best: Option<Compiled> = None;
        for _ in 0..repeats.max(1) {
            let c = compile(rec, &opts)?;
            if best.as_ref().is_none_or(|b| total(&c) < total(b)) {
                best = Some(c);
            }
        }
        if let Some(b) = best {
            runs.push((preset, b));
        }
    }
    let Some((_, exact)) = runs.iter().find(|(p, _)| *p == Preset::Exact) else {
        return Ok(Vec::new());
    };
    let fs_a = f64::from(KeyframeOptions::new(&base.config.keyframes).full_scale_ma) / 1000.0;
    runs.iter()
        .map(|(preset, c)| {
            let (rms, max) = signal_difference(&c.signal, &exact.signal);
            let recall = match truth {
                Some(t) => Some(evaluate_compiled(t, rec, c)?.recall()),
                None => None,
            };
            Ok(TradeRow {
                input: rec.name().to_string(),
                preset: *preset,
                seconds: c.report.seconds,
                transforms: (c.report.transforms_evaluated, c.report.transforms),
                score: c.report.score,
                score_gap_pct: score_gap_pct(c.report.score, exact.report.score),
                rms_vs_exact_pct: 100.0 * rms / fs_a,
                max_vs_exact_pct: 100.0 * max / fs_a,
                tracks_agree_pct: 100.0
                    * track_agreement(c.tracked.as_ref(), exact.tracked.as_ref()),
                bytes: c.report.bytes,
                coverage: c.report.coverage,
                rendered: c.report.rendered_coverage,
                recall,
            })
        })
        .collect()
}

fn total(c: &Compiled) -> f64 {
    c.report.seconds.get(Stage::Total).unwrap_or(f64::INFINITY)
}

/// `(score - reference) / |reference|` in percent; an absolute difference when the
/// reference is 0 (nothing in any workspace), so that 0 vs 0 reads 0.
pub fn score_gap_pct(score: f64, reference: f64) -> f64 {
    if reference == 0.0 {
        100.0 * score
    } else {
        100.0 * (score - reference) / reference.abs()
    }
}

/// RMS and largest difference between two 1 kHz signals over all ticks and channels,
/// in amperes; the shorter one is taken as silent (0 A) past its end.
pub(crate) fn signal_difference(a: &[[f64; CHANNELS]], b: &[[f64; CHANNELS]]) -> (f64, f64) {
    let n = a.len().max(b.len());
    if n == 0 {
        return (0.0, 0.0);
    }
    let silent = [0.0; CHANNELS];
    let (mut sum2, mut max) = (0.0f64, 0.0f64);
    for i in 0..n {
        let (x, y) = (a.get(i).unwrap_or(&silent), b.get(i).unwrap_or(&silent));
        for (p, q) in x.iter().zip(y) {
            let d = (p - q).abs();
            sum2 += d * d;
            max = max.max(d);
        }
    }
    ((sum2 / (n * CHANNELS) as f64).sqrt(), max)
}

/// Share of detections that two trackings have in common: per frame, each detection of
/// one is matched to the nearest unmatched detection of the other within the coarser of
/// the two pixel pitches (in mm); matches over the larger of the two detection counts.
/// 1 when neither tracks anything.
pub(crate) fn track_agreement(a: Option<&TrackOutput>, b: Option<&TrackOutput>) -> f64 {
    let points = |t: Option<&TrackOutput>| -> BTreeMap<usize, Vec<(f64, f64)>> {
        let mut m: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
        if let Some(t) = t {
            for tr in &t.trajectories {
                for d in &tr.points {
                    m.entry(d.frame)
                        .or_default()
                        .push(pixel_centre_mm(d.row, d.col, t.pitch_mm()));
                }
            }
        }
        m
    };
    let (pa, pb) = (points(a), points(b));
    let count = |m: &BTreeMap<usize, Vec<(f64, f64)>>| m.values().map(Vec::len).sum::<usize>();
    let (na, nb) = (count(&pa), count(&pb));
    if na.max(nb) == 0 {
        return 1.0;
    }
    let tol = [a, b]
        .iter()
        .flatten()
        .map(|t| t.pitch_mm())
        .fold(0.0f64, f64::max);
    let mut matched = 0;
    for (frame, xs) in &pa {
        let Some(ys) = pb.get(frame) else { continue };
        let mut used = vec![false; ys.len()];
        for &(x, y) in xs {
            let mut best: Option<(usize, f64)> = None;
            for (j, &(u, v)) in ys.iter().enumerate() {
                let d = ((x - u).powi(2) + (y - v).powi(2)).sqrt();
                if !used[j] && d <= tol && best.is_none_or(|(_, bd)| d < bd) {
                    best = Some((j, d));
                }
            }
            if let Some((j, _)) = best {
                used[j] = true;
                matched += 1;
            }
        }
    }
    matched as f64 / na.max(nb) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_of_identical_and_shifted_signals() {
        let a = vec![[0.5; CHANNELS]; 10];
        assert_eq!(signal_difference(&a, &a), (0.0, 0.0));
        let b = vec![[0.25; CHANNELS]; 10];
        assert_eq!(signal_difference(&a, &b), (0.25, 0.25));
        // Past the end of the shorter signal, it counts as silent.
        let (rms, max) = signal_difference(&a, &a[..5]);
        assert_eq!(max, 0.5);
        assert!((rms - (0.125f64).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn score_gaps() {
        assert_eq!(score_gap_pct(-9.0, -10.0), 10.0);
        assert_eq!(score_gap_pct(-10.0, -10.0), 0.0);
        assert_eq!(score_gap_pct(0.0, 0.0), 0.0);
    }

    /// The preset asked takes every assignment, and an assignment into a table it
    /// leaves out is an error; the others leave such an assignment out and say so.
    #[test]
    fn overrides_apply_to_each_preset_where_they_can() {
        let layers = Layers::new(Preset::Touch)
            .set("detect.sigma_k=1.5")
            .set("track.regions.seed_psi=0.12");
        let (both, skipped) = configs(
            &layers,
            &[Preset::Touch, Preset::Paper],
            Some(Preset::Touch),
        )
        .unwrap();
        assert!(both.iter().all(|(_, c)| c.detect.sigma_k == 1.5));
        assert_eq!(both[0].1.track.regions.map(|r| r.seed_psi), Some(0.12));
        assert_eq!(both[1].1.track.regions, None);
        assert_eq!(skipped.len(), 1);
        assert_eq!(skipped[0].0, Preset::Paper);
        assert_eq!(skipped[0].1.table, "track.regions");
        assert!(matches!(
            configs(&layers, &[Preset::Paper], Some(Preset::Paper)),
            Err(ConfigError::Keys { .. })
        ));
    }

    #[test]
    fn nothing_tracked_twice_agrees() {
        assert_eq!(track_agreement(None, None), 1.0);
    }
}
