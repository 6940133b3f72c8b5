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
//! then checked against the blurred movie ([`exact_crop`]): where it would drop a pixel
//! strong enough for a negative detection cost, it is widened to the whole recording in
//! that dimension. What it drops can only score costs of 0 or more, which the min-cost
//! flow never starts or ends a trajectory on. `host/tests/it/compile.rs` shows the compiled
//! stimulus byte-identical with and without the crop.

use std::ops::Range;

use ndarray::{ArrayView3, Axis, Slice};
use serde::Serialize;

use crate::config::{Config, Sampling};
use crate::placement::Placement;
use crate::rendering::signals::{self, ChannelSignals, Source};
use crate::stage::Stage;
use crate::tracking::detect::{detect_with, detection_cost, Detections};
use crate::tracking::preprocess::{preprocess, Blurred};
use crate::tracking::track::{link, TrackError, TrackOutput};
use touch_protocol::CHANNELS;

/// The part of a tared recording the heavy stages look at, in frames and sensor cells.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Crop {
    /// Frames `[start, end)` after the tare and trim.
    pub frames: Range<usize>,
    /// Cell rows `[start, end)`.
    pub rows: Range<usize>,
    /// Cell columns `[start, end)`.
    pub cols: Range<usize>,
}

impl Crop {
    /// No crop: the whole recording of shape `(frames, rows, cols)`.
    pub fn whole((t, r, c): (usize, usize, usize)) -> Self {
        Crop {
            frames: 0..t,
            rows: 0..r,
            cols: 0..c,
        }
    }
}

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

/// Stages 1-3 on the crop: blur everything (for the statistics), detect and track
/// inside the crop. Trajectories come back in whole-recording frames and pixels;
/// `blurred.frames` holds only the crop's frames (frame `crop.frames.start` first).
///
/// The crop is first checked against the blurred movie and widened where it would drop
/// a pixel that could score a negative detection cost (see [`exact_crop`]); the crop
/// actually used is returned. `lap` is called after each stage with the stage.
pub fn track_cropped(
    tared: ArrayView3<f64>,
    crop: &Crop,
    cfg: &Config,
    sampling: &Sampling,
    lap: &mut dyn FnMut(Stage),
) -> Result<(TrackOutput, Crop), TrackError> {
    let mut window = preprocess(tared, &cfg.preprocess, sampling)?;
    let crop = exact_crop(crop, &window, cfg);
    // Narrow the view to the window without copying the movie.
    window
        .frames
        .slice_axis_inplace(Axis(0), Slice::from(crop.frames.clone()));
    lap(Stage::Preprocess);
    let k = sampling.upsample;
    let (rows, cols) = (
        crop.rows.start * k..crop.rows.end * k,
        crop.cols.start * k..crop.cols.end * k,
    );
    let found = detect_with(&window, &cfg.detect, k);
    let detections = shift_and_clip(&found, crop.frames.start, tared.dim().0, &rows, &cols);
    lap(Stage::Detect);
    let trajectories = link(&detections, &cfg.track, sampling)?;
    lap(Stage::Track);
    let tracked = TrackOutput {
        blurred: window,
        detections,
        trajectories,
    };
    Ok((tracked, crop))
}

/// The crop, widened to the whole recording in time and/or space wherever a blurred
/// pixel it would drop is strong enough for a negative detection cost.
///
/// Outside such pixels every detection costs at least 0, so the min-cost flow never
/// starts or ends a trajectory on one (dropping it from a path's end lowers the cost)
/// and, in time, cannot use one to bridge two contacts either (a path only moves
/// forward, and the window holds every frame between the first and the last strong
/// one). The cost only falls as the pressure rises, so the strongest dropped pixel
/// decides.
pub fn exact_crop(crop: &Crop, blurred: &Blurred, cfg: &Config) -> Crop {
    let (t, h, w) = blurred.frames.dim();
    let k = cfg.preprocess.upsample;
    // The strongest pixel each part of the crop would drop; one cost evaluation each.
    let may_score = |v: f64| {
        blurred.std > 0.0
            && blurred.std.is_finite()
            && detection_cost((v - blurred.mean) / blurred.std, &cfg.detect) < 0.0
    };
    let strongest = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::NEG_INFINITY, f64::max);
    let mut out = crop.clone();
    let dropped_in_time = strongest(
        &mut (0..t)
            .filter(|f| !crop.frames.contains(f))
            .flat_map(|f| blurred.frames.index_axis(Axis(0), f).into_iter().copied()),
    );
    if may_score(dropped_in_time) {
        out.frames = 0..t;
    }
    let (rows, cols) = (
        crop.rows.start * k..crop.rows.end * k,
        crop.cols.start * k..crop.cols.end * k,
    );
    let mut dropped_in_space = f64::NEG_INFINITY;
    for f in out.frames.clone() {
        for ((r, c), &v) in blurred.frames.index_axis(Axis(0), f).indexed_iter() {
            if v > dropped_in_space && !(rows.contains(&r) && cols.contains(&c)) {
                dropped_in_space = v;
            }
        }
    }
    if may_score(dropped_in_space) {
        out.rows = 0..h / k.max(1);
        out.cols = 0..w / k.max(1);
    }
    out
}

/// Detections of the window, moved to whole-recording frames and limited to the
/// crop's pixels; frames outside the window are empty.
fn shift_and_clip(
    found: &Detections,
    offset: usize,
    frames: usize,
    rows: &Range<usize>,
    cols: &Range<usize>,
) -> Detections {
    let mut all = Vec::with_capacity(found.all.len());
    let mut frame_start = vec![0; offset + 1];
    for t in 0..found.frames() {
        all.extend(
            found
                .in_frame(t)
                .iter()
                .filter(|d| rows.contains(&d.row) && cols.contains(&d.col))
                .map(|d| {
                    let mut d = *d;
                    d.frame += offset;
                    d
                }),
        );
        frame_start.push(all.len());
    }
    frame_start.resize(frames + 1, all.len());
    Detections { all, frame_start }
}

/// Stage 5 ([`signals::actuator_signals`]) on the crop's frames, padded with silence to
/// `frames` frames: the signals of the whole recording.
pub fn padded_actuator_signals(
    tracked: &TrackOutput,
    placement: &Placement,
    crop: &Crop,
    frames: usize,
) -> ChannelSignals {
    let offset = crop.frames.start;
    let local: Vec<_> = tracked
        .trajectories
        .iter()
        .map(|t| {
            let mut t = t.clone();
            t.frames.iter_mut().for_each(|f| *f -= offset);
            t
        })
        .collect();
    let inner = signals::actuator_signals(
        &local,
        &placement.selected,
        &placement.circles,
        tracked.blurred.frames.view(),
        tracked.pitch_mm(),
    );
    let pad = |v: &Vec<f64>| {
        let mut out = vec![0.0; frames];
        out[offset..offset + v.len()].copy_from_slice(v);
        out
    };
    let pad_source = |v: &Vec<Source>| {
        let mut out = vec![Source::Silent; frames];
        out[offset..offset + v.len()].copy_from_slice(v);
        out
    };
    ChannelSignals {
        psi: std::array::from_fn::<_, CHANNELS, _>(|c| pad(&inner.psi[c])),
        source: std::array::from_fn::<_, CHANNELS, _>(|c| pad_source(&inner.source[c])),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    fn blurred(frames: Array3<f64>) -> Blurred {
        let n = frames.len() as f64;
        let mean = frames.sum() / n;
        let std = (frames.mapv(|v| (v - mean).powi(2)).sum() / n).sqrt();
        Blurred {
            frames,
            mean,
            std,
            pitch_mm: 25.4 / 7.0,
        }
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
        let quiet = exact_crop(&crop, &blurred(frames.clone()), &cfg);
        assert_eq!(quiet, crop);

        let mut late = frames.clone();
        late[[8, 3, 3]] = 1.0; // a second contact after the window
        assert_eq!(exact_crop(&crop, &blurred(late), &cfg).frames, 0..10);

        let mut aside = frames.clone();
        aside[[4, 12, 18]] = 1.0; // in the window, outside the cells
        let widened = exact_crop(&crop, &blurred(aside), &cfg);
        assert_eq!(
            (widened.frames, widened.rows, widened.cols),
            (2..6, 0..2, 0..3)
        );
    }
}
