//! The tare on recordings it used to get silently wrong: missing readings in the
//! leading baseline's window, a recording too short to tare, one that begins mid-touch
//! under the paper's baseline, and a touch held longer than half the recording.

use ndarray::Array3;
use touchc_input::recording::Recording;
use touchc_input::sanity::SanityWarning;
use touchc_input::warning::{ErasedBy, InputWarning};
use touchc_model::config::{Preset, ValidConfig};
use touchc_pipeline::compile::{compile, CompileOptions, Compiled, Warning};
use touchc_synth::{self as synth, Gesture, SynthSpec};

fn compiled(data: &Array3<f64>, preset: Preset) -> Compiled {
    let rec = Recording::from_array("rec", data.view()).unwrap();
    let opts = CompileOptions {
        config: ValidConfig::preset(preset),
        ..CompileOptions::default()
    };
    compile(&rec, &opts).unwrap()
}

/// Each channel's strongest output, A.
fn peaks(c: &Compiled) -> [f64; 8] {
    let mut p = [f64::NEG_INFINITY; 8];
    for s in &c.signal {
        for (p, &v) in p.iter_mut().zip(s) {
            *p = p.max(v);
        }
    }
    p
}

/// The `n` cells that carry the most pressure over the recording, (row, col).
fn most_touched(data: &Array3<f64>, n: usize) -> Vec<(usize, usize)> {
    let (_, r, c) = data.dim();
    let mut cells: Vec<((usize, usize), f64)> = (0..r)
        .flat_map(|i| (0..c).map(move |j| (i, j)))
        .map(|(i, j)| {
            let s = data.slice(ndarray::s![.., i, j]);
            ((i, j), s.iter().filter(|v| v.is_finite()).sum::<f64>())
        })
        .collect();
    cells.sort_by(|a, b| b.1.total_cmp(&a.1));
    cells.into_iter().take(n).map(|c| c.0).collect()
}

fn stroke() -> Array3<f64> {
    synth::generate(&SynthSpec {
        gestures: vec![Gesture::Stroke],
        ..SynthSpec::default()
    })
}

/// One NaN reading in the first second of each of the most touched cells used to
/// make each of them "no cell" for the whole recording under the paper's tare: the
/// touch over them vanished and the peaks fell, with no word said. Now they are tared
/// by the readings they have, the stimulus is the clean recording's, and it is said.
#[test]
fn a_nan_in_the_tare_window_loses_no_cell() {
    let clean = stroke();
    let clean_out = compiled(&clean, Preset::Paper);
    assert!(clean_out.report.input_warnings().next().is_none());
    for hit in [4, 12] {
        let mut holed = clean.clone();
        for (k, &(i, j)) in most_touched(&clean, hit).iter().enumerate() {
            holed[[3 + k % 10, i, j]] = f64::NAN;
        }
        let out = compiled(&holed, Preset::Paper);
        let (want, got) = (peaks(&clean_out), peaks(&out));
        for ch in 0..8 {
            assert!(
                (want[ch] - got[ch]).abs() < 0.02,
                "{hit} cells hit: channel {ch} peaks at {} A, clean {} A",
                got[ch],
                want[ch]
            );
        }
        assert!(
            (out.report.coverage - clean_out.report.coverage).abs() < 0.01,
            "{hit} cells hit: coverage {} against {}",
            out.report.coverage,
            clean_out.report.coverage
        );
        assert_eq!(
            out.report.input_warnings().collect::<Vec<_>>(),
            vec![&InputWarning::NanInTareWindow {
                tare_frames: 20,
                cells: hit,
                readings: hit,
                unread_cells: 0,
                quantile: 0.02,
            }]
        );
        // The input's own warning comes first.
        assert!(
            matches!(
                out.report.warnings[0],
                Warning::Input(InputWarning::NanInTareWindow { .. })
            ),
            "{:?}",
            out.report.warnings
        );
    }
}

/// A cell with no reading at all in the window, but read later, is tared by its low
/// quantile and named; cells outside the sleeve (never read) are not.
#[test]
fn a_cell_unread_in_the_tare_window_is_tared_by_its_quantile() {
    let clean = stroke();
    let (i, j) = most_touched(&clean, 1)[0];
    let mut holed = clean.clone();
    for t in 0..20 {
        holed[[t, i, j]] = f64::NAN;
    }
    let out = compiled(&holed, Preset::Paper);
    let clean_out = compiled(&clean, Preset::Paper);
    let (want, got) = (peaks(&clean_out), peaks(&out));
    for ch in 0..8 {
        assert!(
            (want[ch] - got[ch]).abs() < 0.02,
            "channel {ch}: {got:?} against {want:?}"
        );
    }
    match &out.report.input_warnings().collect::<Vec<_>>()[..] {
        [InputWarning::NanInTareWindow {
            cells: 1,
            readings: 20,
            unread_cells: 1,
            ..
        }] => {}
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        out.report.warnings[0],
        Warning::Input(InputWarning::NanInTareWindow {
            unread_cells: 1,
            ..
        })
    ));
}

/// `frames` frames of a 8 x 21 sleeve at rest near `rest` psi, with a 2 x 2-cell
/// press of 2 psi at the middle in the frames `pressed` says.
fn pressed(frames: usize, rest: f64, pressed: impl Fn(usize) -> bool) -> Array3<f64> {
    let mut seed = 7u64;
    Array3::from_shape_fn((frames, 8, 21), |(t, r, c)| {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        let noise = 0.004 * ((seed >> 40) as f64 / (1u64 << 24) as f64 * 2.0 - 1.0);
        let d2 = (r as f64 - 3.5).powi(2) + (c as f64 - 10.0).powi(2);
        let touch = if pressed(t) {
            2.0 * (-d2 / 1.5).exp()
        } else {
            0.0
        };
        rest + noise + touch
    })
}

/// The warning of a sensor whose reading falls with pressure.
fn falls(w: &Warning) -> bool {
    matches!(w, Warning::Sanity(SanityWarning::FallsWithTouch { .. }))
}

fn erased(out: &Compiled) -> Option<ErasedBy> {
    out.report.input_warnings().find_map(|w| match w {
        InputWarning::TareErasedTouch { cause, .. } => Some(*cause),
        _ => None,
    })
}

/// One frame of a press is its own robust baseline: the stimulus is silent, and the
/// compile says the tare removed the touch, not that there was none, and claims no
/// coverage of it.
#[test]
fn a_single_frame_is_too_short_to_tare_and_says_so() {
    let out = compiled(&pressed(1, 0.0, |_| true), Preset::Touch);
    assert!(out.report.no_touch);
    assert_eq!(erased(&out), Some(ErasedBy::TooShort { needed: 2 }));
    assert_eq!(out.report.coverage, 0.0);
    assert!(
        matches!(
            out.report.warnings[0],
            Warning::Input(InputWarning::TareErasedTouch {
                frames: 1,
                cause: ErasedBy::TooShort { .. },
                ..
            })
        ),
        "{:?}",
        out.report.warnings
    );
}

/// A press held from the first frame under the paper's leading baseline is tared
/// away: said, with the default preset as the way out, which keeps it.
#[test]
fn a_recording_that_begins_mid_touch_under_the_paper_says_the_tare_removed_it() {
    let rec = pressed(80, 0.0, |t| t < 60);
    let paper = compiled(&rec, Preset::Paper);
    assert!(paper.report.no_touch);
    assert_eq!(erased(&paper), Some(ErasedBy::TouchInTareWindow));
    assert_eq!(paper.report.coverage, 0.0);
    assert!(matches!(
        paper.report.warnings[0],
        Warning::Input(InputWarning::TareErasedTouch {
            cause: ErasedBy::TouchInTareWindow,
            ..
        })
    ));
    // The default preset keeps the touch (rest after it), without that warning.
    let touch = compiled(&rec, Preset::Touch);
    assert!(!touch.report.no_touch);
    assert_eq!(erased(&touch), None);
}

/// A recording with no touch, even on a sensor resting well above 0 psi, is silent
/// with full coverage and no word about the tare.
#[test]
fn a_quiet_recording_is_not_said_to_have_lost_its_touch() {
    for preset in [Preset::Paper, Preset::Touch] {
        for rest in [0.0, 0.5] {
            let out = compiled(&pressed(80, rest, |_| false), preset);
            assert!(out.report.no_touch);
            assert_eq!(erased(&out), None, "{preset:?} at {rest} psi");
            assert_eq!(out.report.coverage, 1.0);
        }
        let one = compiled(&pressed(41, 0.3, |_| false), preset);
        assert!(one.report.input_warnings().next().is_none(), "{preset:?}");
    }
}

/// A press held for most of the recording makes each touched cell's median its
/// touch: the rest then looks like a fall. That is not a falling sensor, and the
/// compile must not advise inverting good data; the same press on a sensor whose
/// reading falls with pressure still gets the warning.
#[test]
fn a_long_touch_is_not_taken_for_a_falling_sensor() {
    let long = pressed(100, 0.0, |t| t < 70);
    let out = compiled(&long, Preset::Touch);
    assert!(
        !out.report.warnings.iter().any(falls),
        "{:?}",
        out.report.warnings
    );
    assert!(!out.report.no_touch);
    // The same recording from a falling sensor: rest minus touch, around 5 psi.
    let mut falling = long.clone();
    falling.mapv_inplace(|v| 5.0 - v);
    let out = compiled(&falling, Preset::Touch);
    assert!(
        out.report.warnings.iter().any(falls),
        "{:?}",
        out.report.warnings
    );
    // And with a short press, both ways as before.
    let short = pressed(100, 0.0, |t| (30..50).contains(&t));
    let mut short_falling = short.clone();
    short_falling.mapv_inplace(|v| 5.0 - v);
    let warned = |a: &Array3<f64>| compiled(a, Preset::Touch).report.warnings.iter().any(falls);
    assert!(!warned(&short));
    assert!(warned(&short_falling));
}
