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

use crate::compile::{compile, CompileError, CompileOptions, Compiled};
use crate::config::{Config, Preset};
use crate::encoding::keyframes::KeyframeOptions;
use crate::geometry::pixel_centre_mm;
use crate::input::recording::Recording;
use crate::input::synth::Truth;
use crate::measure::evaluate::evaluate_compiled;
use crate::stage::{Stage, StageSeconds};
use crate::tracking::track::TrackOutput;
use touch_protocol::CHANNELS;

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
    /// Share of the true contacts tracked (`None` without a truth file).
    pub recall: Option<f64>,
}

/// Compiles `rec` under every preset of `configs` with its config (each `repeats`
/// times, keeping the fastest) and compares each with the `exact` entry; no rows
/// without one. `base` supplies everything but the config. With the `truth` of a
/// synthetic recording (`touchc synth --truth`), each row also gets its recall.
///
/// `configs` is usually [`Preset::ALL`] with [`Config::preset`]; the command line
/// lays its `--config` and `--set` over each preset.
pub fn trade(
    rec: &Recording,
    base: &CompileOptions,
    configs: &[(Preset, Config)],
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
pub fn signal_difference(a: &[[f64; CHANNELS]], b: &[[f64; CHANNELS]]) -> (f64, f64) {
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
pub fn track_agreement(a: Option<&TrackOutput>, b: Option<&TrackOutput>) -> f64 {
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

/// Tick values for a log axis over `lo..hi`: 1, 2 and 5 times the powers of ten
/// inside it, or every whole multiple of them (1 to 9) when that gives fewer than
/// three, so a range within one decade still has labelled ticks.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
        return Vec::new();
    }
    let decades = lo.log10().floor() as i32..=hi.log10().ceil() as i32;
    let within = |mantissas: &[f64]| -> Vec<f64> {
        decades
            .clone()
            .flat_map(|d| mantissas.iter().map(move |m| m * 10f64.powi(d)))
            .filter(|v| (lo..=hi).contains(v))
            .collect()
    };
    let coarse = within(&[1.0, 2.0, 5.0]);
    if coarse.len() >= 3 {
        coarse
    } else {
        within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    }
}

/// A tick value in its shortest form (`0.2`, `50`, `1000`), without the binary
/// representation's tail (`0.30000000000000004`).
#[cfg(feature = "viz")]
fn tick_label(v: f64) -> String {
    let rounded = format!("{v:.6}");
    rounded
        .trim_end_matches('0')
        .trim_end_matches('.')
        .to_string()
}

/// What the chart's title names: the recording, or how many there are.
#[cfg(feature = "viz")]
fn recordings_named(rows: &[TradeRow]) -> String {
    let mut names: Vec<&str> = rows.iter().map(|r| r.input.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    match names.as_slice() {
        [] => "no recording".to_string(),
        [one] => {
            let name = std::path::Path::new(one)
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or(one);
            // At most 60 characters, control and format characters shown as U+FFFD.
            let shown: String = name
                .chars()
                .map(|c| {
                    if c.is_control() || ('\u{200b}'..='\u{206f}').contains(&c) {
                        '\u{fffd}'
                    } else {
                        c
                    }
                })
                .collect();
            if shown.chars().count() > 60 {
                format!("{}\u{2026}", shown.chars().take(59).collect::<String>())
            } else {
                shown
            }
        }
        many => format!("{} recordings", many.len()),
    }
}

/// An SVG of time against error: total compile time (log scale) against the signal's
/// RMS difference to `exact`, one colour per preset, one point per recording and preset,
/// titled with the recording.
#[cfg(feature = "viz")]
pub fn plot_svg(rows: &[TradeRow]) -> Result<String, crate::viz::VizError> {
    use crate::viz::{register_font, VizError, FAMILY};
    use plotters::prelude::*;

    register_font()?;
    let draw = |e: &dyn std::fmt::Display| VizError::Draw(e.to_string());
    let ms = |r: &TradeRow| 1e3 * r.seconds.total();
    let (lo, hi) = rows
        .iter()
        .map(ms)
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo < hi {
        (lo / 1.5, hi * 1.5)
    } else {
        (0.1, 1000.0)
    };
    let top = rows
        .iter()
        .map(|r| r.rms_vs_exact_pct)
        .filter(|v| v.is_finite())
        .fold(1.0f64, f64::max)
        * 1.1;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "touchc trade on {}: compile time against difference to exact",
                    recordings_named(rows)
                ),
                (FAMILY, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            // plotters labels a log axis at powers of ten only: none within a decade.
            .build_cartesian_2d(
                (lo..hi).log_scale().with_key_points(log_ticks(lo, hi)),
                0.0..top,
            )
            .map_err(|e| draw(&e))?;
        chart
            .configure_mesh()
            .x_desc("total compile time, ms (log)")
            .y_desc("RMS difference to exact, % of full scale")
            .x_label_formatter(&|v| tick_label(*v))
            .label_style((FAMILY, 12))
            .draw()
            .map_err(|e| draw(&e))?;
        // One per preset of `Preset::ALL`: a shorter list would drop the last ones.
        let colours: [RGBColor; Preset::ALL.len()] = [
            RGBColor(31, 119, 180),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
        ];
        for (preset, colour) in Preset::ALL.iter().zip(colours) {
            let points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.preset == *preset)
                .map(|r| (ms(r), r.rms_vs_exact_pct))
                .filter(|(x, y)| x.is_finite() && *x > 0.0 && y.is_finite())
                .collect();
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))
                .map_err(|e| draw(&e))?
                .label(preset.name())
                .legend(move |(x, y)| Circle::new((x + 8, y), 5, colour.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FAMILY, 13))
            .draw()
            .map_err(|e| draw(&e))?;
        root.present().map_err(|e| draw(&e))?;
    }
    Ok(svg)
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

    #[test]
    fn nothing_tracked_twice_agrees() {
        assert_eq!(track_agreement(None, None), 1.0);
    }
}
