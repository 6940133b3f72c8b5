//! The features scorer's view of a recording: figures a haptics researcher would read
//! off a touch, in physical units so that sensors of other rates and pitches compare.
//!
//! Pressure is taken above each cell's own baseline (its 10th percentile over the
//! recording: most of a touch recording is the cell at rest), and a cell is in contact
//! when it reads more than a tenth of the recording's peak and well above its noise.
//! From each frame: total pressure, peak, contact area and the pressure-weighted
//! centroid; from their series: duration and bouts of touch, pressure statistics,
//! area, speed along and across the arm, location, and rhythm (band energies and the
//! autocorrelation peak of the total pressure).

use ndarray::{Array2, ArrayView3};

use crate::dataset::Sample;

/// The features' names, in the order [`extract`] returns them.
pub const NAMES: &[&str] = &[
    "length_s",
    "active_s",
    "active_fraction",
    "bouts",
    "bouts_per_s",
    "bout_mean_s",
    "bout_max_s",
    "onset_fraction",
    "offset_fraction",
    "total_mean",
    "total_std",
    "total_max",
    "total_p25",
    "total_p50",
    "total_p75",
    "total_p90",
    "peak_mean",
    "peak_max",
    "peak_std",
    "per_cell_mean",
    "per_cell_std",
    "impulse",
    "total_cv",
    "area_mean",
    "area_std",
    "area_max",
    "area_p50",
    "area_p90",
    "cells_touched",
    "spread_mean",
    "spread_max",
    "rise_mean",
    "rise_max",
    "speed_mean",
    "speed_p50",
    "speed_p90",
    "speed_max",
    "speed_std",
    "along_mean",
    "across_mean",
    "path_mm",
    "net_mm",
    "straightness",
    "reversals_per_s",
    "along_reversals_per_s",
    "change_mean",
    "change_p90",
    "col_mean",
    "col_std",
    "col_min",
    "col_max",
    "row_mean",
    "row_std",
    "row_min",
    "row_max",
    "along_q1",
    "along_q2",
    "along_q3",
    "along_q4",
    "across_h1",
    "across_h2",
    "band_0_1",
    "band_1_2",
    "band_2_4",
    "band_4_8",
    "band_8_up",
    "acf_lag_s",
    "acf_peak",
    "crossings_per_s",
    "peaks_per_s",
    "slope_mean",
    "slope_p90",
];

/// Number of features.
pub const COUNT: usize = NAMES.len();

/// Percentile `q` (0..1) of `v` by nearest rank on a sorted copy; 0 when empty.
fn percentile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn std(v: &[f64]) -> f64 {
    let m = mean(v);
    mean(&v.iter().map(|x| (x - m) * (x - m)).collect::<Vec<_>>()).sqrt()
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// Per-frame series of a recording above its baseline.
struct Series {
    total: Vec<f64>,
    peak: Vec<f64>,
    area: Vec<f64>,
    /// Centroid (row, col) in cells; NaN where nothing touches.
    centroid: Vec<(f64, f64)>,
    spread: Vec<f64>,
    change: Vec<f64>,
    along: Vec<f64>,
    across: Vec<f64>,
    touched: f64,
}

fn series(frames: ArrayView3<f32>) -> Series {
    let (t, rows, cols) = frames.dim();
    let mut base = Array2::<f64>::zeros((rows, cols));
    let mut noise = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        for c in 0..cols {
            let cell: Vec<f64> = (0..t).map(|i| f64::from(frames[[i, r, c]])).collect();
            base[[r, c]] = percentile(&cell, 0.1);
            let med = percentile(&cell, 0.5);
            noise.push(percentile(
                &cell.iter().map(|v| (v - med).abs()).collect::<Vec<_>>(),
                0.5,
            ));
        }
    }
    let above =
        |i: usize, r: usize, c: usize| (f64::from(frames[[i, r, c]]) - base[[r, c]]).max(0.0);
    let peak_all = (0..t)
        .flat_map(|i| (0..rows).flat_map(move |r| (0..cols).map(move |c| (i, r, c))))
        .map(|(i, r, c)| above(i, r, c))
        .fold(0.0, f64::max);
    let thr = (0.1 * peak_all)
        .max(6.0 * 1.4826 * percentile(&noise, 0.5))
        .max(1e-9);
    let mut s = Series {
        total: Vec::with_capacity(t),
        peak: Vec::with_capacity(t),
        area: Vec::with_capacity(t),
        centroid: Vec::with_capacity(t),
        spread: Vec::with_capacity(t),
        change: Vec::with_capacity(t),
        along: vec![0.0; cols],
        across: vec![0.0; rows],
        touched: 0.0,
    };
    let mut ever = Array2::<bool>::from_elem((rows, cols), false);
    for i in 0..t {
        let (mut tot, mut pk, mut area, mut wr, mut wc, mut chg) =
            (0.0, 0.0f64, 0.0, 0.0, 0.0, 0.0);
        for r in 0..rows {
            for c in 0..cols {
                let p = above(i, r, c);
                if i > 0 {
                    chg += (p - above(i - 1, r, c)).abs();
                }
                if p > thr {
                    tot += p;
                    pk = pk.max(p);
                    area += 1.0;
                    wr += p * r as f64;
                    wc += p * c as f64;
                    ever[[r, c]] = true;
                    s.along[c] += p;
                    s.across[r] += p;
                }
            }
        }
        let centre = if area > 0.0 {
            (wr / tot, wc / tot)
        } else {
            (f64::NAN, f64::NAN)
        };
        let mut spread = 0.0;
        if area > 0.0 {
            for r in 0..rows {
                for c in 0..cols {
                    let p = above(i, r, c);
                    if p > thr {
                        spread +=
                            p * ((r as f64 - centre.0).powi(2) + (c as f64 - centre.1).powi(2));
                    }
                }
            }
            spread = (spread / tot).sqrt();
        }
        s.total.push(tot);
        s.peak.push(pk);
        s.area.push(area);
        s.centroid.push(centre);
        s.spread.push(spread);
        s.change.push(chg / peak_all.max(1e-9));
    }
    s.touched = ever.iter().filter(|&&b| b).count() as f64 / (rows * cols) as f64;
    s
}

/// The features of one recording, in [`NAMES`] order; finite for any recording.
pub fn extract(sample: &Sample) -> Vec<f64> {
    let s = series(sample.frames.view());
    let (t, rows, cols) = sample.frames.dim();
    let rate = sample.rate_hz;
    let pitch = sample.pitch_mm;
    let dt = 1.0 / rate;
    let length = t as f64 * dt;
    let active: Vec<usize> = (0..t).filter(|&i| s.area[i] > 0.0).collect();
    let mut out = Vec::with_capacity(COUNT);
    // Duration and bouts.
    let mut bouts = Vec::new();
    let mut run = 0usize;
    for i in 0..=t {
        if i < t && s.area[i] > 0.0 {
            run += 1;
        } else if run > 0 {
            bouts.push(run as f64 * dt);
            run = 0;
        }
    }
    let on = |v: &[f64]| active.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    out.extend([
        length,
        active.len() as f64 * dt,
        active.len() as f64 / t as f64,
        bouts.len() as f64,
        bouts.len() as f64 / length,
        mean(&bouts),
        max(&bouts),
        active.first().map_or(1.0, |&i| i as f64 / t as f64),
        active.last().map_or(0.0, |&i| i as f64 / t as f64),
    ]);
    // Pressure.
    let total = on(&s.total);
    let peak = on(&s.peak);
    let per_cell: Vec<f64> = active.iter().map(|&i| s.total[i] / s.area[i]).collect();
    out.extend([
        mean(&total),
        std(&total),
        max(&total),
        percentile(&total, 0.25),
        percentile(&total, 0.5),
        percentile(&total, 0.75),
        percentile(&total, 0.9),
        mean(&peak),
        max(&peak),
        std(&peak),
        mean(&per_cell),
        std(&per_cell),
        total.iter().sum::<f64>() * dt,
        std(&total) / mean(&total).max(1e-9),
    ]);
    // Area, in cells (rises: frames where the area grows).
    let area = on(&s.area);
    let rises: Vec<f64> = (1..t)
        .map(|i| (s.area[i] - s.area[i - 1]).max(0.0))
        .collect();
    let spread = on(&s.spread);
    out.extend([
        mean(&area),
        std(&area),
        max(&area),
        percentile(&area, 0.5),
        percentile(&area, 0.9),
        s.touched,
        mean(&spread),
        max(&spread),
        mean(&rises),
        max(&rises),
    ]);
    motion(&s, &active, rate, pitch, length, &mut out);
    location(&s, &active, rows, cols, &mut out);
    rhythm(&s.total, rate, length, &mut out);
    debug_assert_eq!(out.len(), COUNT);
    out.iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect()
}

/// Speed of the centroid between consecutive touched frames, mm/s, and its path.
fn motion(s: &Series, active: &[usize], rate: f64, pitch: f64, length: f64, out: &mut Vec<f64>) {
    let (mut speed, mut along, mut across) = (Vec::new(), Vec::new(), Vec::new());
    let (mut reversals, mut along_rev, mut last_dir, mut last_col) = (0.0, 0.0, (0.0, 0.0), 0.0);
    for w in active.windows(2) {
        if w[1] != w[0] + 1 {
            continue;
        }
        let (a, b) = (s.centroid[w[0]], s.centroid[w[1]]);
        let (dr, dc) = ((b.0 - a.0) * pitch * rate, (b.1 - a.1) * pitch * rate);
        speed.push(dr.hypot(dc));
        along.push(dc.abs());
        across.push(dr.abs());
        if dr * last_dir.0 + dc * last_dir.1 < 0.0 {
            reversals += 1.0;
        }
        if dc * last_col < 0.0 {
            along_rev += 1.0;
        }
        if dc.abs() > 1e-9 {
            last_col = dc;
        }
        if dr.hypot(dc) > 1e-9 {
            last_dir = (dr, dc);
        }
    }
    let path: f64 = speed.iter().sum::<f64>() / rate;
    let net = match (active.first(), active.last()) {
        (Some(&i), Some(&j)) => {
            let (a, b) = (s.centroid[i], s.centroid[j]);
            (b.0 - a.0).hypot(b.1 - a.1) * pitch
        }
        _ => 0.0,
    };
    let change = on_all(&s.change, active);
    out.extend([
        mean(&speed),
        percentile(&speed, 0.5),
        percentile(&speed, 0.9),
        max(&speed),
        std(&speed),
        mean(&along),
        mean(&across),
        path,
        net,
        net / path.max(1e-9),
        reversals / length,
        along_rev / length,
        mean(&change),
        percentile(&change, 0.9),
    ]);
}

fn on_all(v: &[f64], active: &[usize]) -> Vec<f64> {
    active.iter().map(|&i| v[i]).collect()
}

/// Where on the sensor the touch was: the centroid's statistics as fractions of the
/// frame, and the share of pressure in each quarter along and half across.
fn location(s: &Series, active: &[usize], rows: usize, cols: usize, out: &mut Vec<f64>) {
    let r: Vec<f64> = active
        .iter()
        .map(|&i| s.centroid[i].0 / rows as f64)
        .collect();
    let c: Vec<f64> = active
        .iter()
        .map(|&i| s.centroid[i].1 / cols as f64)
        .collect();
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    out.extend([
        mean(&c),
        std(&c),
        min(&c),
        max(&c),
        mean(&r),
        std(&r),
        min(&r),
        max(&r),
    ]);
    let share = |v: &[f64], parts: usize| {
        let total: f64 = v.iter().sum::<f64>().max(1e-12);
        (0..parts)
            .map(|p| {
                let (a, b) = (p * v.len() / parts, (p + 1) * v.len() / parts);
                v[a..b].iter().sum::<f64>() / total
            })
            .collect::<Vec<f64>>()
    };
    out.extend(share(&s.along, 4));
    out.extend(share(&s.across, 2));
}

/// Rhythm of the total pressure: the share of its variance in frequency bands, its
/// autocorrelation's first peak, mean crossings, peaks and slopes.
fn rhythm(total: &[f64], rate: f64, length: f64, out: &mut Vec<f64>) {
    let n = total.len();
    let m = mean(total);
    let x: Vec<f64> = total.iter().map(|v| v - m).collect();
    let var: f64 = x.iter().map(|v| v * v).sum::<f64>().max(1e-12);
    // A direct DFT over at most 256 frequencies: recordings are short.
    let bins = (n / 2).clamp(1, 256);
    let mut bands = [0.0f64; 5];
    for k in 1..=bins {
        let f = k as f64 * rate / 2.0 / bins as f64;
        let w = std::f64::consts::TAU * f / rate;
        // The phase advanced by a rotation per frame: no trigonometry in the loop.
        let (step_c, step_s) = (w.cos(), w.sin());
        let (mut re, mut im, mut c, mut s) = (0.0, 0.0, 1.0f64, 0.0f64);
        for v in &x {
            re += v * c;
            im -= v * s;
            (c, s) = (c * step_c - s * step_s, s * step_c + c * step_s);
        }
        let band = match f {
            f if f < 1.0 => 0,
            f if f < 2.0 => 1,
            f if f < 4.0 => 2,
            f if f < 8.0 => 3,
            _ => 4,
        };
        bands[band] += re * re + im * im;
    }
    let energy: f64 = bands.iter().sum::<f64>().max(1e-12);
    out.extend(bands.iter().map(|b| b / energy));
    let (lo, hi) = (
        ((0.1 * rate) as usize).max(1),
        ((2.0 * rate) as usize).min(n.saturating_sub(1)),
    );
    let (mut best, mut lag) = (0.0, 0usize);
    for l in lo..=hi.max(lo) {
        if l >= n {
            break;
        }
        let r: f64 = (0..n - l).map(|i| x[i] * x[i + l]).sum::<f64>() / var;
        if r > best {
            best = r;
            lag = l;
        }
    }
    let crossings = x.windows(2).filter(|w| w[0] * w[1] < 0.0).count() as f64;
    let peaks = total
        .windows(3)
        .filter(|w| w[1] > w[0] && w[1] >= w[2] && w[1] > m)
        .count() as f64;
    let slope: Vec<f64> = total
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() * rate)
        .collect();
    out.extend([
        lag as f64 / rate,
        best,
        crossings / length,
        peaks / length,
        mean(&slope),
        percentile(&slope, 0.9),
    ]);
}
