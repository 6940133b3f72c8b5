//! The fabric grid's touch shows what real captures do (REAL-TOUCH statistics at 54 Hz,
//! cells above 0.08 psi): several local maxima per hand, per-cell runs that often last
//! at most two frames, and a recording that begins mid-touch.

use ndarray::{Array3, Axis};
use touchc_synth::cases::real_like_on;
use touchc_synth::{generate_with_truth, Sensor};

const TOUCH_PSI: f64 = 0.08;

/// Median active cells and median local maxima (3 x 3) over the frames with touch, and
/// the share of per-cell runs above the threshold that last at most two frames.
fn stats(rec: &Array3<f64>) -> (usize, usize, f64) {
    let (t, rows, cols) = rec.dim();
    let mut active = Vec::new();
    let mut maxima = Vec::new();
    for f in rec.axis_iter(Axis(0)) {
        let on = |r: usize, c: usize| f[[r, c]] > TOUCH_PSI;
        let mut n = 0;
        let mut m = 0;
        for r in 0..rows {
            for c in 0..cols {
                if !on(r, c) {
                    continue;
                }
                n += 1;
                let top = (r.saturating_sub(1)..(r + 2).min(rows))
                    .flat_map(|i| (c.saturating_sub(1)..(c + 2).min(cols)).map(move |j| (i, j)))
                    .all(|(i, j)| f[[i, j]] <= f[[r, c]]);
                m += usize::from(top);
            }
        }
        if n > 0 {
            active.push(n);
            maxima.push(m);
        }
    }
    let (mut runs, mut short) = (0, 0);
    for r in 0..rows {
        for c in 0..cols {
            let mut len = 0;
            for f in 0..=t {
                if f < t && rec[[f, r, c]] > TOUCH_PSI {
                    len += 1;
                } else if len > 0 {
                    runs += 1;
                    short += usize::from(len <= 2);
                    len = 0;
                }
            }
        }
    }
    let median = |mut v: Vec<usize>| {
        v.sort_unstable();
        v.get(v.len() / 2).copied().unwrap_or(0)
    };
    (
        median(active),
        median(maxima),
        short as f64 / runs.max(1) as f64,
    )
}

#[test]
fn a_fabric_grid_shows_real_captures_statistics() {
    for case in real_like_on(Sensor::Grid10, 54.0) {
        let (rec, truth) = generate_with_truth(&case.spec);
        let (active, maxima, short) = stats(&rec);
        let what = format!(
            "{}: {active} cells, {maxima} maxima, {short:.2} short",
            case.name
        );
        // REAL-TOUCH: 21-81% of a cell's runs last at most two frames (scratches, whose
        // contact moves a cell a frame, more).
        assert!((0.21..=0.9).contains(&short), "{what}");
        if case.name.starts_with("held hand") || case.name.starts_with("rub") {
            // A hand: tens of cells, several maxima.
            assert!(active >= 10 && maxima >= 2, "{what}");
        }
        if case.name.starts_with("held hand") {
            // On the sensor from the first frame: nothing to tare on there.
            let first = rec.index_axis(Axis(0), 0);
            assert!(
                first.iter().filter(|&&v| v > TOUCH_PSI).count() >= 10,
                "{what}"
            );
            assert_eq!(truth.contacts[0].points[0].frame, 0, "{what}");
        }
    }
}

#[test]
fn the_fabric_reads_the_same_touch_at_any_rate() {
    // The gains and dropouts are functions of time: a frame at the same instant at 20
    // and 54 Hz (1 s = 20 = 54 frames) reads the same cells.
    let at = |rate: f64| {
        let case = real_like_on(Sensor::Grid10, rate)
            .into_iter()
            .find(|c| c.name.starts_with("strokes"))
            .unwrap();
        let spec = touchc_synth::SynthSpec {
            noise_psi: 0.0,
            ..case.spec
        };
        let (rec, _) = generate_with_truth(&spec);
        rec.index_axis(Axis(0), (rate * 2.5).round() as usize)
            .to_owned()
    };
    let (a, b) = (at(20.0), at(54.0));
    for (x, y) in a.iter().zip(b.iter()) {
        assert!((x - y).abs() < 1e-9, "{a:?}\n{b:?}");
    }
}
