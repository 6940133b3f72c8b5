//! "Model only what a scene requires": the no-touch filter, and the crop of the
//! active scene in time and space before the heavy stages.
//!
//! A recording is mostly quiet: sensor noise before the hand arrives and after it
//! leaves, and cells far from the contact. The crop keeps the frames with any reading
//! above the touch threshold plus `crop.time_margin_s` on each side, and the cells'
//! bounding box plus `crop.space_margin_mm` (both rounded up to whole frames and cells
//! at the recording's [`Sampling`]). Detection, tracking and the per-actuator signals
//! run on that window only; everything outside it is silent.
//!
//! The statistics are those of the whole recording: the blur runs on every frame (the
//! cheap stage, a few ms for 705 frames) so that the mean and standard deviation, and
//! with them every detection cost, are bit-identical to the uncropped run. The crop is
//! then checked against the blurred movie (`exact_crop`): where it would drop a pixel
//! strong enough for a negative detection cost, it is widened to the whole recording in
//! that dimension. What it drops can only score costs of 0 or more, which the min-cost
//! flow never starts or ends a trajectory on. `host/tests/it/compile.rs` shows the compiled
//! stimulus byte-identical with and without the crop.

use std::ops::Range;
use std::time::{Duration, Instant};

use ndarray::{s, Array3, ArrayView2, ArrayView3, Axis};

use crate::detect::{detection_cost, frame_candidates, score_candidates, Candidates, Detections};
use crate::flow::FlowError;
use crate::preprocess::{blur_chunks, Blur, BlurOperator, Blurred};
use crate::regions::{cell_points, link_regions};
use crate::track::{link, Linked, TrackError, TrackOutput};
use touchc_model::config::{Config, Sampling};
use touchc_model::crop::Crop;
use touchc_model::stage::{Shares, Stage};

/// Readings above `threshold_psi` in the tared recording (the paper's touch filter).
pub fn touch_readings(tared: ArrayView3<f64>, threshold_psi: f64) -> usize {
    tared.iter().filter(|&&v| v > threshold_psi).count()
}

/// The active scene with its margins; the whole recording when nothing is active.
pub fn active_crop(tared: ArrayView3<f64>, cfg: &Config, sampling: &Sampling) -> Crop {
    let (t, r, c) = tared.dim();
    let thr = cfg.input.touch_threshold_psi;
    let (mut f0, mut f1, mut r0, mut r1, mut c0, mut c1) = (t, 0, r, 0, c, 0);
    for ((f, row, col), &v) in tared.indexed_iter() {
        if v > thr {
            f0 = f0.min(f);
            f1 = f1.max(f + 1);
            r0 = r0.min(row);
            r1 = r1.max(row + 1);
            c0 = c0.min(col);
            c1 = c1.max(col + 1);
        }
    }
    if f0 >= f1 {
        return Crop::whole(tared.dim());
    }
    let widen = |lo: usize, hi: usize, m: usize, n: usize| {
        lo.saturating_sub(m)..hi.saturating_add(m).min(n)
    };
    let time = sampling.frames_ceil(cfg.crop.time_margin_s);
    let space = sampling.cells_ceil(cfg.crop.space_margin_mm);
    Crop {
        frames: widen(f0, f1, time, t),
        rows: widen(r0, r1, space, r),
        cols: widen(c0, c1, space, c),
    }
}

/// The strongest blurred pixel of one frame, over the whole frame and outside a crop's
/// pixel box: all [`exact_crop`] needs of the movie, so that the movie need not be kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FrameExtremes {
    /// Strongest pixel of the frame.
    pub all: f64,
    /// Strongest pixel outside the box (`-inf` when the box covers the frame).
    pub aside: f64,
}

impl FrameExtremes {
    /// The extremes of `frame` for the pixel box `rows` x `cols`.
    pub fn of(frame: ArrayView2<f64>, rows: &Range<usize>, cols: &Range<usize>) -> Self {
        // Eight running maxima by comparison (vectorises; `f64::max` folds one NaN-aware
        // step after another). The same maximum: a NaN is skipped either way.
        fn max(values: &[f64]) -> f64 {
            let larger = |m: f64, v: f64| if v > m { v } else { m };
            let mut lanes = [f64::NEG_INFINITY; 8];
            let mut chunks = values.chunks_exact(8);
            for chunk in &mut chunks {
                for (l, &v) in lanes.iter_mut().zip(chunk) {
                    *l = larger(*l, v);
                }
            }
            let tail = chunks
                .remainder()
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, larger);
            lanes.into_iter().fold(tail, larger)
        }
        let (mut all, mut aside) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut visit = |r: usize, row: &[f64]| {
            let n = row.len();
            let (c0, c1) = (cols.start.min(n), cols.end.min(n).max(cols.start.min(n)));
            let (left, inside, right) = (max(&row[..c0]), max(&row[c0..c1]), max(&row[c1..]));
            let outside = left.max(right);
            all = all.max(inside).max(outside);
            aside = aside.max(if rows.contains(&r) {
                outside
            } else {
                inside.max(outside)
            });
        };
        for (r, row) in frame.outer_iter().enumerate() {
            match row.as_slice() {
                Some(row) => visit(r, row),
                None => visit(r, &row.to_vec()),
            }
        }
        FrameExtremes { all, aside }
    }
}

/// The crop's cells as upsampled pixel ranges `(rows, cols)`.
fn pixel_box(crop: &Crop, k: usize) -> (Range<usize>, Range<usize>) {
    (
        crop.rows.start * k..crop.rows.end * k,
        crop.cols.start * k..crop.cols.end * k,
    )
}

/// Stages 1-3 on the crop, streaming: one pass blurs each frame, finds its detection
/// candidates and its `FrameExtremes`, and drops it. The statistics are those of the
/// whole recording; the crop is then checked (`exact_crop`) and the detections of its
/// frames and cells are scored and linked. Memory is a few runs of blurred frames plus
/// the candidates, whatever the recording's length. The pass runs on the current rayon
/// pool, in runs of frames (`blur_chunks`); the result does not depend on the number
/// of threads.
///
/// With `keep_scene` the blurred frames are also kept in `blurred.frames` (the whole
/// recording; previews draw them) and the scored detections in `detections`; otherwise
/// `blurred.frames` has no frames, stage 5 recomputes the few it reads
/// (`recomputed_actuator_signals`), and `detections` is empty once linked. Trajectories are in
/// whole-recording frames and pixels. The crop actually used is returned. `lap` is
/// called with the stages whose work has just been done and the share of the time since
/// its previous call that each took (the pass's time is split between blurring and
/// detection by the time its threads spent on each).
pub fn track_cropped(
    tared: ArrayView3<f64>,
    crop: &Crop,
    cfg: &Config,
    sampling: &Sampling,
    keep_scene: bool,
    lap: &mut dyn FnMut(&Shares),
) -> Result<(TrackOutput, Crop), TrackError> {
    let (t, r, c) = tared.dim();
    let k = sampling.upsample;
    let (h, w) = BlurOperator::new(r, c, &Blur::new(&cfg.preprocess, sampling))?.out_dim();
    let mut movie = Array3::<f64>::zeros(if keep_scene { (t, h, w) } else { (0, h, w) });
    let (rows, cols) = pixel_box(crop, k);
    let mut extremes = Vec::with_capacity(t);
    let mut candidates = Candidates::with_frames(t);
    let (mut busy, mut detecting) = (Duration::ZERO, Duration::ZERO);
    let stats = blur_chunks(
        tared,
        &cfg.preprocess,
        sampling,
        |run| Run {
            first: run.start,
            extremes: Vec::with_capacity(run.len()),
            candidates: Candidates::with_frames(run.len()),
            movie: keep_scene.then(|| Array3::zeros((run.len(), h, w))),
            detecting: Duration::ZERO,
        },
        |run, f, frame| {
            run.extremes.push(FrameExtremes::of(frame, &rows, &cols));
            if let Some(movie) = &mut run.movie {
                movie.index_axis_mut(Axis(0), f - run.first).assign(&frame);
            }
            let clock = Instant::now();
            run.candidates.push_frame_with(match &cfg.track.regions {
                Some(regions) => cell_points(frame, k, regions.footprint_psi),
                None => frame_candidates(frame, &cfg.detect, cfg.detect.split.as_ref(), k),
            });
            run.detecting += clock.elapsed();
        },
        |run, took| {
            extremes.extend(run.extremes);
            candidates.append(&run.candidates);
            if let Some(frames) = run.movie {
                let end = run.first + frames.dim().0;
                movie.slice_mut(s![run.first..end, .., ..]).assign(&frames);
            }
            busy += took;
            detecting += run.detecting;
        },
    )?;
    let detect_share = if busy > Duration::ZERO {
        (detecting.as_secs_f64() / busy.as_secs_f64()).min(1.0)
    } else {
        0.0
    };
    lap(&[
        (Stage::Preprocess, 1.0 - detect_share),
        (Stage::Detect, detect_share),
    ]);
    let crop = exact_crop(crop, &extremes, stats.mean, stats.std, (r, c), cfg);
    let (rows, cols) = pixel_box(&crop, k);
    candidates
        .retain(|f, &(r, c, _)| crop.frames.contains(&f) && rows.contains(&r) && cols.contains(&c));
    let detections = score_candidates(&candidates, stats.mean, stats.std, &cfg.detect);
    drop(candidates);
    lap(&[(Stage::Detect, 1.0)]);
    let linked = link_detections(&detections, cfg, sampling)?;
    lap(&[(Stage::Track, 1.0)]);
    let detection_count = detections.all.len();
    let detections = if keep_scene {
        detections
    } else {
        // On an hour of touch the detections outweigh the recording.
        Detections::empty(t)
    };
    let tracked = TrackOutput {
        blurred: Blurred {
            frames: movie,
            mean: stats.mean,
            std: stats.std,
            pitch_mm: stats.pitch_mm,
        },
        detections,
        detection_count,
        trajectories: linked.trajectories,
        flow_work: linked.work,
        flow_budget_reached: linked.budget_reached,
    };
    Ok((tracked, crop))
}

/// Stage 3 on the scored detections: contacts as regions with `track.regions`, else
/// the min-cost flow.
fn link_detections(
    detections: &Detections,
    cfg: &Config,
    sampling: &Sampling,
) -> Result<Linked, TrackError> {
    Ok(match &cfg.track.regions {
        Some(regions) => Linked {
            trajectories: link_regions(detections, regions, &cfg.track, sampling),
            work: 0,
            budget_reached: false,
        },
        None => link(detections, &cfg.track, sampling).map_err(|e| match e {
            FlowError::TooManyEdges { limit } => TrackError::TooDense {
                detections: detections.all.len(),
                limit,
            },
            e => TrackError::Flow(e),
        })?,
    })
}

/// What the pass of [`track_cropped`] finds in one run of frames, from its first.
struct Run {
    first: usize,
    extremes: Vec<FrameExtremes>,
    candidates: Candidates,
    /// The run's blurred frames, with `keep_scene`.
    movie: Option<Array3<f64>>,
    /// Time spent finding candidates.
    detecting: Duration,
}

/// The crop, widened to the whole recording in time and/or space wherever a blurred
/// pixel it would drop is strong enough for a negative detection cost. `extremes` has
/// one entry per frame, for the crop's pixel box; `cells` is the sensor's `(rows,
/// cols)`; `mean` and `std` are the movie's.
///
/// Outside such pixels every detection costs at least 0, so the min-cost flow never
/// starts or ends a trajectory on one (dropping it from a path's end lowers the cost)
/// and, in time, cannot use one to bridge two contacts either (a path only moves
/// forward, and the window holds every frame between the first and the last strong
/// one). The cost only falls as the pressure rises, so the strongest dropped pixel
/// decides.
pub(crate) fn exact_crop(
    crop: &Crop,
    extremes: &[FrameExtremes],
    mean: f64,
    std: f64,
    cells: (usize, usize),
    cfg: &Config,
) -> Crop {
    let may_score = |v: f64| {
        std > 0.0 && std.is_finite() && detection_cost((v - mean) / std, &cfg.detect) < 0.0
    };
    let mut out = crop.clone();
    let dropped_in_time = extremes
        .iter()
        .enumerate()
        .filter(|(f, _)| !crop.frames.contains(f))
        .fold(f64::NEG_INFINITY, |m, (_, e)| m.max(e.all));
    if may_score(dropped_in_time) {
        out.frames = 0..extremes.len();
    }
    let dropped_in_space = extremes
        .get(out.frames.clone())
        .unwrap_or_default()
        .iter()
        .fold(f64::NEG_INFINITY, |m, e| m.max(e.aside));
    if may_score(dropped_in_space) {
        out.rows = 0..cells.0;
        out.cols = 0..cells.1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array2, Array3};

    /// [`exact_crop`] of `crop` on a whole blurred movie (7 pixels per cell).
    fn crop_on(crop: &Crop, frames: &Array3<f64>, cfg: &Config) -> Crop {
        let n = frames.len() as f64;
        let mean = frames.sum() / n;
        let std = (frames.mapv(|v| (v - mean).powi(2)).sum() / n).sqrt();
        let (rows, cols) = pixel_box(crop, 7);
        let extremes: Vec<_> = frames
            .outer_iter()
            .map(|f| FrameExtremes::of(f, &rows, &cols))
            .collect();
        let (_, h, w) = frames.dim();
        exact_crop(crop, &extremes, mean, std, (h / 7, w / 7), cfg)
    }

    #[test]
    fn extremes_split_the_frame_at_the_box() {
        let mut f = Array2::zeros((4, 5));
        f[[1, 1]] = 3.0; // inside rows 1..3, cols 1..4
        f[[2, 4]] = 2.0; // in a box row, right of the box
        f[[0, 0]] = 1.0; // above the box
        let e = FrameExtremes::of(f.view(), &(1..3), &(1..4));
        assert_eq!((e.all, e.aside), (3.0, 2.0));
        let whole = FrameExtremes::of(f.view(), &(0..4), &(0..5));
        assert_eq!((whole.all, whole.aside), (3.0, f64::NEG_INFINITY));
    }

    #[test]
    fn the_crop_widens_where_it_would_drop_a_scoring_pixel() {
        let cfg = Config::default();
        // 10 frames of 2 x 3 cells (14 x 21 pixels); the crop keeps frames 2..6,
        // cell row 0 and cell columns 0..2.
        let crop = Crop {
            frames: 2..6,
            rows: 0..1,
            cols: 0..2,
        };
        let mut frames = Array3::from_elem((10, 14, 21), 0.001);
        frames[[3, 3, 3]] = 1.0; // the contact, inside
        let quiet = crop_on(&crop, &frames, &cfg);
        assert_eq!(quiet, crop);

        let mut late = frames.clone();
        late[[8, 3, 3]] = 1.0; // a second contact after the window
        assert_eq!(crop_on(&crop, &late, &cfg).frames, 0..10);

        let mut aside = frames.clone();
        aside[[4, 12, 18]] = 1.0; // in the window, outside the cells
        let widened = crop_on(&crop, &aside, &cfg);
        assert_eq!(
            (widened.frames, widened.rows, widened.cols),
            (2..6, 0..2, 0..3)
        );
    }
}
