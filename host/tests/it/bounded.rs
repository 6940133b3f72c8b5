//! Work and memory follow the touch, not the input's shape: a flat plateau (a
//! saturated sensor) is one contact, not a detection at every pixel.

use ndarray::{Array2, Array3};
use touchc::config::{Config, Metadata, MetadataOverrides, Preset, Sampling};
use touchc::input::recording::Recording;
use touchc::tracking::detect::{frame_points, local_maxima};
use touchc::tracking::preprocess::{Blur, BlurOperator};
use touchc::tracking::track::track;

/// The touch preset's lattice on 8 x 21 cells: every second row and column.
const LATTICE: usize = 4 * 11;

/// `[frames, 8, 21]`: zero, except `cells` (rows, cols) at 5 psi in frames `on`.
fn saturated(
    frames: usize,
    on: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
) -> Array3<f64> {
    Array3::from_shape_fn((frames, 8, 21), |(t, r, c)| {
        if on.contains(&t) && rows.contains(&r) && cols.contains(&c) {
            5.0
        } else {
            0.0
        }
    })
}

/// One blurred 8 x 21 frame under `cfg`, at 20 Hz and 25.4 mm cells.
fn blurred(frame: &Array2<f64>, cfg: &Config) -> Array2<f64> {
    let rec =
        Recording::from_array("frame", frame.clone().insert_axis(ndarray::Axis(0)).view()).unwrap();
    let sampling = Sampling::new(
        &Metadata::resolve(&MetadataOverrides::default(), &rec, cfg),
        cfg,
    );
    let (r, c) = frame.dim();
    BlurOperator::new(r, c, &Blur::new(&cfg.preprocess, &sampling))
        .unwrap()
        .apply(frame.view())
}

/// A 6 x 10-cell patch at 5 psi blurs into a plateau, flat up to the blur's rounding
/// (a pattern of values one ulp apart): one maximum, at the patch's centre, not one per
/// pixel of the pattern's top level; the whole sensor saturated is a constant frame,
/// no maximum. The touch preset's lattice still covers the patch.
#[test]
fn a_saturated_patch_is_one_local_maximum() {
    let cfg = Config::default();
    let patch = saturated(1, 0..1, 1..7, 5..15).index_axis_move(ndarray::Axis(0), 0);
    let b = blurred(&patch, &cfg);
    let maxima = local_maxima(b.view(), cfg.detect.min_value_psi);
    assert_eq!(maxima.len(), 1, "{:?}", &maxima[..maxima.len().min(4)]);
    let (r, c, _) = maxima[0];
    // The patch spans pixel rows 7..49 and columns 35..105: centre (27.5, 69.5).
    assert!((27..=28).contains(&r) && (69..=70).contains(&c), "{r}, {c}");

    let whole = Array2::from_elem((8, 21), 5.0);
    let b = blurred(&whole, &cfg);
    assert!(
        b.iter().any(|&v| v != b[[0, 0]]),
        "the blur's rounding is not flat"
    );
    assert!(local_maxima(b.view(), cfg.detect.min_value_psi).is_empty());

    let split = cfg
        .detect
        .split
        .as_ref()
        .expect("touch splits flat contacts");
    let points = frame_points(b.view(), &cfg.detect, Some(split), 7);
    assert!(
        !points.is_empty() && points.len() <= LATTICE,
        "{}",
        points.len()
    );
}

/// The whole sensor saturated for a second (once a detection per pixel per frame and a
/// flow graph of 6.4 GB), and a 6 x 10-cell patch for 10 s (once 2.3 GB and half a
/// minute): tracked with a few detections per frame and little flow work, under both
/// presets.
#[test]
fn a_saturated_sensor_tracks_with_bounded_work() {
    for (name, rec) in [
        ("whole sensor, 1 s", saturated(60, 20..40, 0..8, 0..21)),
        ("6 x 10 cells, 10 s", saturated(240, 20..220, 1..7, 5..15)),
    ] {
        let rec = Recording::from_array(name, rec.view()).unwrap();
        for preset in [Preset::Touch, Preset::Paper] {
            let cfg = Config::preset(preset);
            let out = track(&rec, &cfg).unwrap();
            let frames = out.detections.frames();
            let most = out
                .detections
                .frame_start
                .windows(2)
                .map(|w| w[1] - w[0])
                .max();
            assert!(most.unwrap_or(0) <= LATTICE, "{name}, {preset:?}: {most:?}");
            assert!(out.detections.all.len() <= frames * LATTICE);
            assert!(!out.flow_budget_reached, "{name}, {preset:?}");
            assert!(
                out.flow_work < 5_000_000,
                "{name}, {preset:?}: {} edges scanned",
                out.flow_work
            );
        }
    }
}
