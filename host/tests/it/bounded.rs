//! Work and memory follow the touch, not the input's shape: a flat plateau (a
//! saturated sensor) is one contact, not a detection at every pixel.

use ndarray::{Array2, Array3};
use touchc_input::recording::Recording;
use touchc_model::config::{
    Config, Metadata, MetadataOverrides, Preset, Sampling, Split, ValidConfig,
};
use touchc_pipeline::track::track;
use touchc_tracking::detect::{frame_points, local_maxima};
use touchc_tracking::preprocess::{Blur, BlurOperator};

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
        &Metadata::resolve(&MetadataOverrides::default(), &rec.file_metadata(), cfg),
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
/// no maximum. The lattice of flat contacts (`Split::LATTICE`) still covers the patch.
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

    let points = frame_points(b.view(), &cfg.detect, Some(&Split::LATTICE), 7);
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
            let cfg = ValidConfig::preset(preset);
            let out = track(&rec, &cfg).unwrap();
            let frames = out.detections.frames();
            let most = out
                .detections
                .frame_start
                .windows(2)
                .map(|w| w[1] - w[0])
                .max();
            // A region's detections are the sensor's cells (8 x 21 at most); the
            // lattice's, at most its points.
            let bound = if cfg.track.regions.is_some() {
                8 * 21
            } else {
                LATTICE
            };
            assert!(most.unwrap_or(0) <= bound, "{name}, {preset:?}: {most:?}");
            assert!(out.detections.all.len() <= frames * bound);
            assert!(!out.flow_budget_reached, "{name}, {preset:?}");
            assert!(
                out.flow_work < 5_000_000,
                "{name}, {preset:?}: {} edges scanned",
                out.flow_work
            );
        }
    }
}

/// The edge limit of the tracking graph ends the build with an error naming it, before
/// the graph takes the memory.
#[test]
fn the_tracking_graph_stops_at_its_edge_limit() {
    use touchc_tracking::flow::FlowError;
    use touchc_tracking::track::link_within;
    let rec = Recording::from_array("patch", saturated(240, 20..220, 1..7, 5..15).view()).unwrap();
    // The flow's graph: the default without regions (its lattice of flat contacts).
    let mut cfg = Config::default();
    cfg.track.regions = None;
    let cfg = cfg.validated().unwrap();
    let out = track(&rec, &cfg).unwrap();
    let sampling = Sampling::new(
        &Metadata::resolve(&MetadataOverrides::default(), &rec.file_metadata(), &cfg),
        &cfg,
    );
    assert!(link_within(&out.detections, &cfg.track, &sampling, 1 << 20).is_ok());
    assert_eq!(
        link_within(&out.detections, &cfg.track, &sampling, 10),
        Err(FlowError::TooManyEdges { limit: 10 })
    );
}

/// An archive entry whose header claims more than an entry may take is refused from
/// its header, before a byte of it is inflated (a 1 MB file may inflate to gigabytes).
#[test]
fn an_npz_entry_beyond_the_budget_is_refused_from_its_header() {
    use crate::poison::{npy, zip, Entry};
    use touchc_input::recording::{RecordingError, MEMBER_BUDGET_BYTES};
    // float64 frames of 8 x 21: one frame more than the budget holds.
    let frames = MEMBER_BUDGET_BYTES / (8 * 21 * 8) + 1;
    let header = npy("<f8", false, &format!("({frames}, 8, 21)"), &[]);
    let needed = header.len() as u64 + frames * 8 * 21 * 8;
    let bytes = zip(&[Entry {
        declared: Some(u32::try_from(needed).unwrap()),
        ..Entry::deflated("pressure.npy", header)
    }]);
    match Recording::from_bytes("bomb.npz", &bytes) {
        Err(e @ RecordingError::MemberTooLarge { .. }) => {
            let text = e.to_string();
            assert!(
                text.starts_with("bomb.npz: entry \"pressure.npy\""),
                "{text}"
            );
        }
        other => panic!("{other:?}"),
    }
}

/// An archive holding both `pressure` and `pressure.npy`: numpy's `np.load(f)["pressure"]`
/// reads the entry named exactly `pressure`, and so does touchc.
#[test]
fn an_npz_key_reads_the_entry_numpy_reads() {
    use crate::poison::{small_npy, zip, Entry};
    let bytes = zip(&[
        Entry::stored("pressure.npy", small_npy(50, 1.0)),
        Entry::stored("pressure", small_npy(50, 2.0)),
    ]);
    let rec = Recording::from_bytes("both.npz", &bytes).unwrap();
    assert!(rec.data().iter().all(|&v| v == 2.0));
    // Either order in the archive.
    let bytes = zip(&[
        Entry::stored("pressure", small_npy(50, 2.0)),
        Entry::stored("pressure.npy", small_npy(50, 1.0)),
    ]);
    let rec = Recording::from_bytes("both.npz", &bytes).unwrap();
    assert!(rec.data().iter().all(|&v| v == 2.0));
}

/// A batch holding a saturated sensor and an archive bomb (five megabytes of end
/// records, and an entry claiming gigabytes): the good files and the plateau compile,
/// the bombs are named, and the batch exits non-zero.
#[test]
fn a_batch_with_a_plateau_and_bombs_compiles_its_good_files() {
    use crate::bin::{s, touchc};
    use crate::poison::{f64s, npy, zip, Entry};
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let npy_of = |a: &Array3<f64>| {
        let (t, r, c) = a.dim();
        npy(
            "<f8",
            false,
            &format!("({t}, {r}, {c})"),
            &f64s(a.iter().copied()),
        )
    };
    let moving = crate::common::moving_blobs(120, 1, 3);
    let good = write("good.npy", &npy_of(&moving));
    let plateau = write("plateau.npy", &npy_of(&saturated(60, 20..40, 0..8, 0..21)));
    // Five megabytes of end records, each claiming an entry where none is.
    let mut records = b"PK\x03\x04".to_vec();
    records.extend_from_slice(&[20, 0, 0, 0, 0, 0, 0, 0, 0x21, 0]);
    records.extend_from_slice(&[0; 16]);
    while records.len() < 5 << 20 {
        records.extend_from_slice(b"PK\x05\x06");
        records.extend_from_slice(&[0, 0, 0, 0, 1, 0, 1, 0, 46, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    }
    let records = write("records.npz", &records);
    let frames = 2_000_000_000u64 / (8 * 21 * 4);
    let header = npy("<f4", false, &format!("({frames}, 8, 21)"), &[]);
    let needed = header.len() as u64 + frames * 8 * 21 * 4;
    let claim = write(
        "claim.npz",
        &zip(&[Entry {
            declared: Some(u32::try_from(needed).unwrap()),
            ..Entry::deflated("pressure.npy", header)
        }]),
    );
    let out_dir = dir.path().join("out");
    let out = touchc(&[
        "compile",
        s(&good),
        s(&records),
        s(&plateau),
        s(&claim),
        "--out-dir",
        s(&out_dir),
    ]);
    let err = crate::bin::refused(&out);
    for (stem, compiled) in [
        ("good", true),
        ("plateau", true),
        ("records", false),
        ("claim", false),
    ] {
        assert_eq!(
            out_dir.join(format!("{stem}.touch")).exists(),
            compiled,
            "{stem}: {err}"
        );
    }
    assert!(
        err.contains("records.npz") && err.contains("end-of-central-directory"),
        "{err}"
    );
    assert!(err.contains("claim.npz") && err.contains("needs"), "{err}");
}

/// `track` streams as the compile does: the same statistics, detections counted and
/// trajectories as the run that keeps the blurred movie, bit for bit, without the movie
/// (an hour's is 4.7 GB) or the detections.
#[test]
fn tracking_streams_like_the_compile() {
    use touchc_pipeline::track::track_streaming;
    let rec =
        Recording::from_array("blobs", crate::common::moving_blobs(400, 3, 5).view()).unwrap();
    for preset in [Preset::Touch, Preset::Paper] {
        let cfg = ValidConfig::preset(preset);
        let none = MetadataOverrides::default();
        let kept = track(&rec, &cfg).unwrap();
        let streamed = track_streaming(&rec, &cfg, &none).unwrap();
        assert_eq!(streamed.blurred.frames.dim().0, 0);
        assert!(streamed.detections.all.is_empty());
        assert!(kept.blurred.frames.dim().0 >= 360);
        assert_eq!(streamed.detection_count, kept.detections.all.len());
        assert!(streamed.detection_count > 0);
        assert_eq!(streamed.trajectories, kept.trajectories);
        assert_eq!(
            (streamed.mean().to_bits(), streamed.std().to_bits()),
            (kept.mean().to_bits(), kept.std().to_bits())
        );
    }
}

/// A preview of a compile that streamed (no blurred movie kept) is the preview of the
/// compile that kept it, byte for byte: each frame is blurred again as it is drawn.
#[test]
fn a_preview_draws_a_streamed_compile_as_the_kept_one() {
    use touchc::viz::preview;
    use touchc_pipeline::compile::{compile, CompileOptions};
    let rec =
        Recording::from_array("blobs", crate::common::moving_blobs(160, 2, 9).view()).unwrap();
    let run = |keep_scene| {
        compile(
            &rec,
            &CompileOptions {
                fit: true,
                crop: false,
                keep_scene,
                ..CompileOptions::default()
            },
        )
        .unwrap()
    };
    let (kept, streamed) = (run(true), run(false));
    let movie =
        |c: &touchc_pipeline::compile::Compiled| c.tracked.as_ref().unwrap().blurred.frames.dim().0;
    assert_eq!((movie(&kept) > 0, movie(&streamed)), (true, 0));
    let rate = kept.report.metadata.rate_hz.value;
    assert_eq!(
        preview::png_frame(&streamed, &rec, 60, rate).unwrap(),
        preview::png_frame(&kept, &rec, 60, rate).unwrap()
    );
    assert_eq!(
        preview::gif(&streamed, &rec, 10, rate).unwrap(),
        preview::gif(&kept, &rec, 10, rate).unwrap()
    );
    // A cropped compile cannot be previewed, movie or not.
    let cropped = compile(&rec, &CompileOptions::default()).unwrap();
    assert!(matches!(
        preview::png_frame(&cropped, &rec, 0, rate),
        Err(preview::PreviewError::Cropped)
    ));
}
