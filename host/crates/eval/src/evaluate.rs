//! Tracking measured against the truth of a synthetic recording ([`touchc_synth::Truth`]):
//! what the trajectories keep of the touch that was there, and what they invent.
//!
//! Four figures, all in sensor cells and frames of the tared recording, so sensors,
//! rates and presets compare on one scale:
//!
//! * **recall**: the share of true contacts that one trajectory *follows* (lies within
//!   `FOLLOW_CELLS` of the contact's centre) in more than half the frames of the
//!   contact's life (the frames it presses above the touch threshold);
//! * **splits**: times a followed contact is handed from one trajectory to another
//!   (none of the trajectories that followed it in the last frame it was followed in
//!   follows it now): a stroke cut into pieces, each a separate contact to the placement;
//! * **merges**: trajectories that follow two or more true contacts (each point goes to
//!   the nearest contact present in its frame, and a contact counts once it holds two of
//!   the trajectory's points, or all of a shorter life);
//! * **false contacts**: trajectories that lie near no pressing contact in most of their
//!   frames (sensor noise, the quiet stretches before and after a touch);
//! * **coverage**: [`touchc_pipeline::coverage`]'s share of the touch pressure near a trajectory.

use std::collections::BTreeMap;

use ndarray::ArrayView3;
use serde::Serialize;

use touchc_input::recording::{Recording, RecordingError};
use touchc_model::config::Sampling;
use touchc_model::trajectory::Trajectory;
use touchc_pipeline::compile::Compiled;
use touchc_pipeline::coverage::{self, ContactPoint, Coverage, DEFAULT_RADIUS_CELLS};
use touchc_synth::{Truth, TruthContact, TruthPoint};

/// A trajectory follows a contact in a frame when it lies this close to the contact's
/// centre, in cells (the radius of the coverage definition).
pub(crate) const FOLLOW_CELLS: f64 = DEFAULT_RADIUS_CELLS;

/// A contact in a frame counts as touching (for false contacts) above this pressure, psi:
/// well above sensor noise (about 0.003 psi), well below any touch.
pub(crate) const PRESENT_PSI: f64 = 0.02;

/// What tracking made of one true contact.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactResult {
    /// The contact's id in the truth.
    pub id: usize,
    /// Its gesture.
    pub gesture: String,
    /// Frames it presses above the touch threshold (including frames the tare or trim
    /// dropped, which no trajectory can follow).
    pub life: usize,
    /// Most of those frames one trajectory follows it in.
    pub followed: usize,
    /// Times it passes from one trajectory to another (see the module docs).
    pub splits: usize,
}

impl ContactResult {
    /// More than half its life followed by one trajectory.
    pub(crate) fn recalled(&self) -> bool {
        2 * self.followed > self.life
    }
}

/// The four figures of a tracking result against the truth (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// Per true contact that presses above the touch threshold in some frame.
    pub contacts: Vec<ContactResult>,
    /// Trajectories tracked.
    pub trajectories: usize,
    /// Trajectories that follow two or more true contacts.
    pub merges: usize,
    /// Handovers between trajectories, summed over the true contacts.
    pub splits: usize,
    /// Trajectories where nothing presses most of the time.
    pub false_contacts: usize,
    /// Coverage of the touch pressure by the trajectories.
    pub coverage: Coverage,
}

impl Evaluation {
    /// True contacts recalled.
    pub(crate) fn recalled(&self) -> usize {
        self.contacts.iter().filter(|c| c.recalled()).count()
    }

    /// `recalled / contacts`; 1 when there is no contact to recall.
    pub fn recall(&self) -> f64 {
        if self.contacts.is_empty() {
            1.0
        } else {
            self.recalled() as f64 / self.contacts.len() as f64
        }
    }

    /// One line: recall, merges, splits, false contacts, coverage.
    pub fn summary(&self) -> String {
        format!(
            "recall {:.2} ({}/{}), merges {}, splits {}, false {}, coverage {:.2}, {} trajectories",
            self.recall(),
            self.recalled(),
            self.contacts.len(),
            self.merges,
            self.splits,
            self.false_contacts,
            self.coverage.ratio(),
            self.trajectories
        )
    }
}

/// Measures what `compiled` (a compile of `rec`) tracked against `truth`, on the tared
/// recording and at the sampling the compile itself used (its report carries both).
pub fn evaluate_compiled(
    truth: &Truth,
    rec: &Recording,
    compiled: &Compiled,
) -> Result<Evaluation, RecordingError> {
    let cfg = &compiled.report.config;
    let sampling = Sampling::new(&compiled.report.metadata, cfg);
    let tared = rec.tare(&cfg.input, &sampling)?;
    let trajectories = compiled
        .tracked
        .as_ref()
        .map_or(&[][..], |t| &t.trajectories[..]);
    Ok(evaluate(
        truth,
        sampling.frames(cfg.input.trim_s),
        tared.view(),
        cfg.input.touch_threshold_psi,
        trajectories,
        sampling.upsample,
    ))
}

/// Measures `trajectories` (pixels of a grid upsampled `upsample` times, frames of
/// `tared`) against `truth`, whose frame `f` is frame `f - offset` of `tared` (the frames
/// the tare and trim dropped at the start). `threshold_psi` is the touch threshold.
pub fn evaluate(
    truth: &Truth,
    offset: usize,
    tared: ArrayView3<f64>,
    threshold_psi: f64,
    trajectories: &[Trajectory],
    upsample: usize,
) -> Evaluation {
    let frames = tared.dim().0;
    let present = present_by_frame(truth, offset, frames);
    let tracks: Vec<Vec<ContactPoint>> = trajectories
        .iter()
        .map(|t| coverage::contact_points(std::slice::from_ref(t), upsample))
        .collect();
    let life = lives(truth, offset, threshold_psi);
    let contacts = truth
        .contacts
        .iter()
        .zip(&life)
        .filter(|(_, life)| !life.is_empty())
        .map(|(c, life)| contact_result(c, life, offset, &tracks))
        .collect::<Vec<_>>();
    let (mut merges, mut false_contacts) = (0, 0);
    for track in &tracks {
        let (merged, false_contact) = judge_track(track, &present, &life, frames);
        merges += usize::from(merged);
        false_contacts += usize::from(false_contact);
    }
    let all: Vec<ContactPoint> = tracks.into_iter().flatten().collect();
    let coverage = coverage::measure(tared, threshold_psi, &all, DEFAULT_RADIUS_CELLS);
    let splits = contacts.iter().map(|c: &ContactResult| c.splits).sum();
    Evaluation {
        contacts,
        trajectories: trajectories.len(),
        merges,
        splits,
        false_contacts,
        coverage,
    }
}

/// Squared distance, in cells, from a trajectory point to a truth point.
fn dist2(p: &ContactPoint, q: &TruthPoint) -> f64 {
    (p.row - q.row).powi(2) + (p.col - q.col).powi(2)
}

/// The truth points of each tared frame, with the index of their contact.
fn present_by_frame(truth: &Truth, offset: usize, frames: usize) -> Vec<Vec<(usize, TruthPoint)>> {
    let mut present: Vec<Vec<(usize, TruthPoint)>> = vec![Vec::new(); frames];
    for (k, c) in truth.contacts.iter().enumerate() {
        for p in &c.points {
            if let Some(f) = p.frame.checked_sub(offset).filter(|&f| f < frames) {
                present[f].push((k, *p));
            }
        }
    }
    present
}

/// The life of each contact: the tared frames it presses above `threshold_psi` in.
/// Frames the tare and trim dropped count as life too (negative or past the end, never
/// followed): touch at the start or end of a recording is touch lost.
fn lives(truth: &Truth, offset: usize, threshold_psi: f64) -> Vec<Vec<i64>> {
    truth
        .contacts
        .iter()
        .map(|c| {
            c.points
                .iter()
                .filter(|p| p.pressure_psi > threshold_psi)
                .map(|p| p.frame as i64 - offset as i64)
                .collect()
        })
        .collect()
}

/// How long the best of `tracks` follows contact `c` over its `life`, and how often it
/// is handed from one trajectory to another.
fn contact_result(
    c: &TruthContact,
    life: &[i64],
    offset: usize,
    tracks: &[Vec<ContactPoint>],
) -> ContactResult {
    let follow2 = FOLLOW_CELLS * FOLLOW_CELLS;
    let at = |f: usize| {
        c.points
            .iter()
            .find(|p| p.frame.checked_sub(offset) == Some(f))
    };
    let follows = |p: &ContactPoint| {
        life.contains(&(p.frame as i64)) && at(p.frame).is_some_and(|q| dist2(p, q) <= follow2)
    };
    // Frames, not points: a region has a point per cell of its footprint.
    let followed = tracks
        .iter()
        .map(|track| {
            let mut frames: Vec<usize> = track
                .iter()
                .filter(|p| follows(p))
                .map(|p| p.frame)
                .collect();
            frames.dedup();
            frames.len()
        })
        .max()
        .unwrap_or(0);
    // Which trajectories follow it in each frame of its life, in frame order.
    let mut by_frame: BTreeMap<usize, Vec<usize>> = Default::default();
    for (j, track) in tracks.iter().enumerate() {
        for p in track.iter().filter(|p| follows(p)) {
            by_frame.entry(p.frame).or_default().push(j);
        }
    }
    ContactResult {
        id: c.id,
        gesture: c.gesture.name().to_string(),
        life: life.len(),
        followed,
        splits: handovers(&by_frame),
    }
}

/// Frames (in order) whose followers share none with the previous followed frame's.
fn handovers(by_frame: &BTreeMap<usize, Vec<usize>>) -> usize {
    let mut splits = 0;
    let mut last: Option<&Vec<usize>> = None;
    for now in by_frame.values() {
        if last.is_some_and(|l| !l.iter().any(|j| now.contains(j))) {
            splits += 1;
        }
        last = Some(now);
    }
    splits
}

/// Whether `track` is a merge (claims two or more contacts) and whether it is a false
/// contact (near no pressing contact in most of its points).
fn judge_track(
    track: &[ContactPoint],
    present: &[Vec<(usize, TruthPoint)>],
    life: &[Vec<i64>],
    frames: usize,
) -> (bool, bool) {
    let mut held = vec![0usize; life.len()];
    let mut touching = 0;
    for p in track.iter().filter(|p| p.frame < frames) {
        let near = present[p.frame]
            .iter()
            .filter(|(_, q)| q.pressure_psi > PRESENT_PSI)
            .map(|(k, q)| (*k, dist2(p, q), q.radius_cells.max(FOLLOW_CELLS)))
            .filter(|&(_, d2, r)| d2 <= r * r)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, _, _)) = near {
            touching += 1;
            held[k] += 1;
        }
    }
    let claimed = held
        .iter()
        .zip(life)
        .filter(|(&n, life)| n >= 2 || (n >= 1 && n >= life.len()))
        .count();
    (claimed >= 2, 2 * touching < track.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;
    use touchc_model::trajectory::Columns;
    use touchc_synth::{Gesture, Sensor, TruthContact};

    fn point(frame: usize, row: f64, col: f64, pressure_psi: f64) -> TruthPoint {
        TruthPoint {
            frame,
            t_s: frame as f64 / 20.0,
            row,
            col,
            x_mm: (col + 0.5) * 25.4,
            y_mm: (row + 0.5) * 25.4,
            radius_cells: 1.5,
            radius_mm: 1.5 * 25.4,
            pressure_psi,
        }
    }

    /// Two contacts on a 4 x 20 frame of 10 frames: A at row 1 moving right one cell
    /// per frame over frames 0-4, B at row 1 moving right over frames 5-9 from column 10.
    fn truth() -> Truth {
        let a = (0..5).map(|f| point(f, 1.0, f as f64, 1.0)).collect();
        let b = (5..10)
            .map(|f| point(f, 1.0, 10.0 + f as f64, 1.0))
            .collect();
        Truth {
            sensor: Sensor::Sleeve,
            rate_hz: 20.0,
            pitch_mm: 25.4,
            frames: 10,
            rows: 4,
            cols: 20,
            contacts: vec![
                TruthContact {
                    id: 0,
                    gesture: Gesture::Stroke,
                    points: a,
                },
                TruthContact {
                    id: 1,
                    gesture: Gesture::Stroke,
                    points: b,
                },
            ],
        }
    }

    /// The tared recording the truth describes: 1 psi at each contact's cell.
    fn tared(truth: &Truth) -> Array3<f64> {
        let mut rec = Array3::zeros((truth.frames, truth.rows, truth.cols));
        for c in &truth.contacts {
            for p in &c.points {
                rec[[p.frame, p.row as usize, p.col as usize]] = p.pressure_psi;
            }
        }
        rec
    }

    /// A trajectory through cells `(frame, row, col)`, at upsampling 1.
    fn traj(points: &[(usize, usize, usize)]) -> Trajectory {
        Trajectory::try_from(Columns {
            frames: points.iter().map(|p| p.0).collect(),
            rows: points.iter().map(|p| p.1).collect(),
            cols: points.iter().map(|p| p.2).collect(),
            costs: vec![-1.0; points.len()],
            values: vec![1.0; points.len()],
        })
        .unwrap()
    }

    #[test]
    fn two_trajectories_on_two_contacts_recall_both_without_merges() {
        let t = truth();
        let a = traj(&[(0, 1, 0), (1, 1, 1), (2, 1, 2), (3, 1, 3)]);
        let b = traj(&[(6, 1, 16), (7, 1, 17), (8, 1, 18)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[a, b], 1);
        assert_eq!(e.recall(), 1.0, "{e:?}");
        assert_eq!((e.merges, e.false_contacts), (0, 0));
        // 7 of the 10 touched readings lie on a trajectory.
        assert!((e.coverage.ratio() - 0.7).abs() < 1e-12, "{e:?}");
    }

    #[test]
    fn following_half_the_life_is_not_enough() {
        let t = truth();
        // A for 2 of its 5 frames, B for 3 of 5 (more than half).
        let a = traj(&[(0, 1, 0), (1, 1, 1)]);
        let b = traj(&[(5, 1, 15), (6, 1, 16), (7, 1, 17)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[a, b], 1);
        assert_eq!(e.recalled(), 1);
        assert_eq!(e.recall(), 0.5);
        // Points further than two cells do not follow.
        let far = traj(&[(5, 1, 18), (6, 1, 19), (7, 1, 19)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[far], 1);
        assert_eq!(e.contacts[1].followed, 1);
    }

    #[test]
    fn one_trajectory_across_two_contacts_is_a_merge() {
        let t = truth();
        let both: Vec<_> = (0..10)
            .map(|f| (f, 1, if f < 5 { f } else { 10 + f }))
            .collect();
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[traj(&both)], 1);
        assert_eq!(e.merges, 1);
        assert_eq!(e.recall(), 1.0);
    }

    #[test]
    fn a_contact_handed_from_one_trajectory_to_the_next_is_a_split() {
        let t = truth();
        // A in two pieces (frames 0-1, then 2-4): one split; B followed by two
        // trajectories side by side, one of which goes on: no split.
        let a1 = traj(&[(0, 1, 0), (1, 1, 1)]);
        let a2 = traj(&[(2, 1, 2), (3, 1, 3), (4, 1, 4)]);
        let b1 = traj(&[(5, 1, 15), (6, 1, 16), (7, 1, 17), (8, 1, 18)]);
        let b2 = traj(&[(5, 2, 15), (6, 2, 16)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[a1, a2, b1, b2], 1);
        assert_eq!((e.contacts[0].splits, e.contacts[1].splits), (1, 0));
        assert_eq!(e.splits, 1);
        // A frame nobody follows in between is no split by itself.
        let gap = traj(&[(5, 1, 15), (6, 1, 16), (8, 1, 18), (9, 1, 19)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[gap], 1);
        assert_eq!(e.splits, 0);
    }

    #[test]
    fn a_trajectory_where_nothing_presses_is_false() {
        let t = truth();
        // Row 3, far from A; then frames 5-9 at column 0, far from B.
        let noise = traj(&[(0, 3, 15), (1, 3, 15), (2, 3, 15)]);
        let quiet = traj(&[(6, 1, 0), (7, 1, 0)]);
        let e = evaluate(&t, 0, tared(&t).view(), 0.08, &[noise, quiet], 1);
        assert_eq!(e.false_contacts, 2);
        assert_eq!(e.recall(), 0.0);
    }

    #[test]
    fn the_offset_maps_truth_frames_onto_the_tared_frames() {
        let t = truth();
        // The tare dropped 3 frames: truth frame 5 is tared frame 2; of A's life only
        // frames 3 and 4 (tared 0 and 1) remain to follow.
        let rec = tared(&t);
        let cut = rec.slice(ndarray::s![3.., .., ..]);
        let b = traj(&[(2, 1, 15), (3, 1, 16), (4, 1, 17)]);
        let e = evaluate(&t, 3, cut, 0.08, &[b], 1);
        assert_eq!(e.contacts.len(), 2);
        assert_eq!((e.contacts[0].life, e.contacts[1].life), (5, 5));
        assert_eq!(e.recalled(), 1);
        // Pressure below the touch threshold is no life.
        let mut faint = truth();
        faint.contacts[0]
            .points
            .iter_mut()
            .for_each(|p| p.pressure_psi = 0.05);
        let e = evaluate(&faint, 0, tared(&faint).view(), 0.08, &[], 1);
        assert_eq!(e.contacts.len(), 1);
    }
}
