//! Stage 3 for contacts as moving regions ([`Regions`], the `touch` preset): a contact
//! is the cells a hand presses, one trajectory per hand, whose points in a frame are the
//! cells of its footprint.
//!
//! Detections here are sensor cells (their centre pixels, `cell_points`) above the
//! footprint threshold, scored as any detection. Per frame the cells fall into regions
//! (cells within [`Regions::join_cells`] of each other); a region continues the contact
//! nearest to it, and a contact survives frames without a region up to the bridge
//! (`track.bridge`). Everything is decided frame by frame in row-major and creation
//! order, so the result is deterministic and does not depend on the number of threads.

use ndarray::ArrayView2;

use crate::detect::{Detection, Detections, Evidence};
use touchc_model::config::{Regions, Sampling, TrackConfig};
use touchc_model::trajectory::{Point, Trajectory};

/// The cells of one blurred frame (`[R k, C k]` pixels, `k = upsample`) whose centre
/// pixel reads more than `min_value`, as `(row, col, value)` of that pixel in row-major
/// order, each scored by its own value.
pub(crate) fn cell_points(
    frame: ArrayView2<f64>,
    upsample: usize,
    min_value: f64,
) -> Vec<((usize, usize, f64), Evidence)> {
    let k = upsample.max(1);
    let (h, w) = frame.dim();
    let centre = |i: usize| i * k + k / 2;
    let mut out = Vec::new();
    for r in (0..h / k).map(centre) {
        for c in (0..w / k).map(centre) {
            let v = frame[[r, c]];
            if v > min_value {
                out.push(((r, c, v), Evidence::own(v)));
            }
        }
    }
    out
}

/// One frame's region: indexes of its cells among the frame's detections (ascending, so
/// row-major) and its peak value.
struct Region {
    cells: Vec<usize>,
    peak: f64,
}

/// A contact being tracked.
struct Contact {
    /// Cells `(row, col)` of its footprint in the last frame it was seen in.
    last: Vec<(i64, i64)>,
    /// That frame.
    last_frame: usize,
    /// Its points so far, frame after frame.
    points: Vec<Point>,
}

/// The regions of one frame's cells `at` (cell coordinates, row-major): cells whose row
/// and column both differ by at most `join` are one region. In order of their first
/// cell.
fn regions_of(at: &[(i64, i64)], values: &[f64], join: i64) -> Vec<Region> {
    let n = at.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for i in 0..n {
        // Row-major: later cells more than `join` rows down are all too far.
        for j in i + 1..n {
            if at[j].0 - at[i].0 > join {
                break;
            }
            if (at[j].1 - at[i].1).abs() <= join {
                let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                // The smaller root keeps the region in order of its first cell.
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut index = vec![usize::MAX; n];
    let mut out: Vec<Region> = Vec::new();
    for (i, &value) in values.iter().enumerate().take(n) {
        let root = find(&mut parent, i);
        if index[root] == usize::MAX {
            index[root] = out.len();
            out.push(Region {
                cells: Vec::new(),
                peak: f64::NEG_INFINITY,
            });
        }
        let r = &mut out[index[root]];
        r.cells.push(i);
        r.peak = r.peak.max(value);
    }
    out
}

/// Squared distance in cells between the nearest cells of `a` and `b`.
fn gap2(a: &[(i64, i64)], b: &[(i64, i64)]) -> i64 {
    let mut best = i64::MAX;
    for &(r, c) in a {
        for &(s, d) in b {
            best = best.min((r - s).pow(2) + (c - d).pow(2));
        }
    }
    best
}

/// The trajectories of `detections` (cells, `cell_points`) as moving regions, in
/// order of their first frame (ties: their first cell's row-major order).
pub fn link_regions(
    detections: &Detections,
    regions: &Regions,
    cfg: &TrackConfig,
    sampling: &Sampling,
) -> Vec<Trajectory> {
    let k = sampling.upsample.max(1);
    let missing = cfg.bridge.map_or(0, |b| b.missing_frames(sampling.rate_hz));
    // How far a contact may move in one frame, in cells.
    let step_cells = cfg.max_speed_mm_s / sampling.rate_hz / sampling.pitch_mm;
    let join = regions.join_cells.max(1) as i64;
    let mut live: Vec<Contact> = Vec::new();
    let mut done: Vec<Contact> = Vec::new();
    for t in 0..detections.frames() {
        let found = detections.in_frame(t);
        // Contacts unseen for longer than the bridge are over.
        let (over, kept): (Vec<Contact>, Vec<Contact>) = live
            .into_iter()
            .partition(|c| t - c.last_frame > missing + 1);
        // A contact's points grew by doubling; what it no longer needs goes back now, for
        // the contacts still to come, not when the hour is tracked (a quarter of the
        // trajectories' memory).
        done.extend(over.into_iter().map(|mut c| {
            c.points.shrink_to_fit();
            c
        }));
        live = kept;
        if found.is_empty() {
            continue;
        }
        let at: Vec<(i64, i64)> = found
            .iter()
            .map(|d| ((d.row / k) as i64, (d.col / k) as i64))
            .collect();
        let values: Vec<f64> = found.iter().map(|d| d.value).collect();
        let frame_regions = regions_of(&at, &values, join);
        let owner = assign(&frame_regions, &at, &live, join, step_cells, t);
        let mut footprints: Vec<Vec<usize>> = vec![Vec::new(); live.len()];
        for (region, own) in frame_regions.iter().zip(&owner) {
            match own {
                Some(c) => footprints[*c].extend(&region.cells),
                // Only a region that reaches the seed starts a contact (hysteresis).
                None if region.peak >= regions.seed_psi => {
                    live.push(Contact {
                        last: Vec::new(),
                        last_frame: t,
                        points: Vec::new(),
                    });
                    footprints.push(region.cells.clone());
                }
                None => {}
            }
        }
        for (contact, mut cells) in live.iter_mut().zip(footprints) {
            if cells.is_empty() {
                continue;
            }
            cells.sort_unstable();
            let peak = cells.iter().map(|&i| values[i]).fold(0.0, f64::max);
            contact.last = cells.iter().map(|&i| at[i]).collect();
            contact.last_frame = t;
            contact
                .points
                .extend(cells.iter().map(|&i| point(&found[i], peak)));
        }
    }
    done.extend(live);
    done.retain(|c| !c.points.is_empty());
    if done.len() > cfg.max_trajectories {
        // As the flow's units: the contacts that explain the most (lowest total cost)
        // are kept, ties to the earlier one.
        let cost = |c: &Contact| c.points.iter().map(|p| p.cost).sum::<f64>();
        let mut order: Vec<(f64, usize)> = done.iter().map(cost).zip(0..).collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut keep = vec![false; done.len()];
        for &(_, i) in order.iter().take(cfg.max_trajectories) {
            keep[i] = true;
        }
        let mut k = keep.into_iter();
        done.retain(|_| k.next().unwrap_or(false));
    }
    // Creation order is the order of the first frame, then of the first cell.
    done.sort_by_key(|c| c.points.first().map(|p| (p.frame, p.row, p.col)));
    done.into_iter()
        .map(|c| Trajectory { points: c.points })
        .collect()
}

/// A footprint cell as a trajectory point: its cost is the detection's (never above
/// 0: a weak rim cell is part of a contact that is there), weighted by its share of the
/// contact's peak, so that placement puts its circles where the contact presses most.
fn point(d: &Detection, peak: f64) -> Point {
    let share = if peak > 0.0 { d.value / peak } else { 0.0 };
    Point {
        frame: d.frame,
        row: d.row,
        col: d.col,
        cost: d.cost.min(0.0) * share.clamp(0.0, 1.0),
        value: d.value,
    }
}

/// Which live contact each region continues (`None`: a new one, or noise). First every
/// region within `join` cells of a contact's last footprint goes to the nearest such
/// contact (a hand split by flicker stays one); then a contact that found none takes
/// the nearest free region within its gate (`step_cells` per frame since it was last
/// seen, plus `join`), and the free regions within `join` of that one.
fn assign(
    regions: &[Region],
    at: &[(i64, i64)],
    live: &[Contact],
    join: i64,
    step_cells: f64,
    t: usize,
) -> Vec<Option<usize>> {
    let cells = |r: &Region| r.cells.iter().map(|&i| at[i]).collect::<Vec<_>>();
    let region_cells: Vec<Vec<(i64, i64)>> = regions.iter().map(cells).collect();
    let mut owner: Vec<Option<usize>> = vec![None; regions.len()];
    let mut near: Vec<Vec<i64>> = Vec::with_capacity(regions.len());
    for (ri, rc) in region_cells.iter().enumerate() {
        let d: Vec<i64> = live.iter().map(|c| gap2(rc, &c.last)).collect();
        let best = (0..live.len())
            .filter(|&c| d[c] <= join * join)
            .min_by_key(|&c| (d[c], c));
        owner[ri] = best;
        near.push(d);
    }
    let mut has = vec![false; live.len()];
    for o in owner.iter().flatten() {
        has[*o] = true;
    }
    // Fast contacts: pairs (distance, contact, region) within the gate, nearest first.
    let mut pairs: Vec<(i64, usize, usize)> = Vec::new();
    for (c, contact) in live.iter().enumerate().filter(|(c, _)| !has[*c]) {
        let gate = step_cells * (t - contact.last_frame) as f64 + join as f64;
        for (ri, d) in near.iter().enumerate() {
            if owner[ri].is_none() && (d[c] as f64) <= gate * gate {
                pairs.push((d[c], c, ri));
            }
        }
    }
    pairs.sort_unstable();
    for (_, c, ri) in pairs {
        if has[c] || owner[ri].is_some() {
            continue;
        }
        has[c] = true;
        owner[ri] = Some(c);
        // The rest of the same hand, split from this region by flicker.
        for rj in 0..regions.len() {
            if owner[rj].is_none() && gap2(&region_cells[rj], &region_cells[ri]) <= join * join {
                owner[rj] = Some(c);
            }
        }
    }
    owner
}

#[cfg(test)]
mod tests {
    use super::*;
    use touchc_model::config::{Bridge, Config, Preset};

    /// Cells `(row, col, value)` per frame as detections on a 7-pixel grid.
    fn frames(cells: &[Vec<(usize, usize, f64)>]) -> Detections {
        let mut all = Vec::new();
        let mut frame_start = vec![0];
        for (frame, f) in cells.iter().enumerate() {
            let mut f = f.clone();
            f.sort_by_key(|c| (c.0, c.1));
            all.extend(f.iter().map(|&(r, c, value)| Detection {
                frame,
                row: r * 7 + 3,
                col: c * 7 + 3,
                value,
                cost: -3.0,
                fixed: false,
            }));
            frame_start.push(all.len());
        }
        Detections { all, frame_start }
    }

    fn count(cells: &[Vec<(usize, usize, f64)>], rate_hz: f64) -> usize {
        let mut cfg = Config::preset(Preset::Touch).track;
        cfg.bridge = Some(Bridge {
            max_missing_s: 0.06,
            cost_per_missing: 0.5,
        });
        let regions = Regions {
            seed_psi: 0.08,
            footprint_psi: 0.03,
            join_cells: 2,
        };
        let sampling = Sampling {
            rate_hz,
            pitch_mm: 25.4,
            upsample: 7,
        };
        link_regions(&frames(cells), &regions, &cfg, &sampling).len()
    }

    #[test]
    fn a_hand_that_flickers_apart_stays_one_contact() {
        // A 2 x 4 hand whose middle flickers out every other frame: two pieces two
        // cells apart, then one.
        let whole: Vec<_> = (0..2)
            .flat_map(|r| (3..7).map(move |c| (r, c, 0.5)))
            .collect();
        let split: Vec<_> = whole.iter().copied().filter(|&(_, c, _)| c != 4).collect();
        let movie: Vec<_> = (0..20)
            .map(|f| {
                if f % 2 == 0 {
                    whole.clone()
                } else {
                    split.clone()
                }
            })
            .collect();
        assert_eq!(count(&movie, 54.0), 1);
    }

    #[test]
    fn two_hands_stay_two_and_a_lift_of_150_ms_ends_a_stroke() {
        let hands: Vec<_> = (0..10)
            .map(|_| vec![(1, 1, 0.5), (1, 2, 0.4), (1, 7, 0.5), (1, 8, 0.4)])
            .collect();
        assert_eq!(count(&hands, 20.0), 2);
        // One frame unseen at 20 Hz (50 ms) is bridged; three (150 ms) are not.
        let one = |f: usize| vec![(1, f, 0.5)];
        let bridged: Vec<_> = (0..10)
            .map(|f| if f == 5 { vec![] } else { one(f) })
            .collect();
        assert_eq!(count(&bridged, 20.0), 1);
        let lifted: Vec<_> = (0..12)
            .map(|f| if (5..8).contains(&f) { vec![] } else { one(f) })
            .collect();
        assert_eq!(count(&lifted, 20.0), 2);
    }

    #[test]
    fn at_most_max_trajectories_contacts_are_kept_the_strongest() {
        // Three taps one after another, the middle one weakest (its cells' cost is the
        // same, but it has one cell where the others have two).
        let movie = vec![
            vec![(1, 1, 0.5), (1, 2, 0.5)],
            vec![],
            vec![],
            vec![],
            vec![(4, 4, 0.5)],
            vec![],
            vec![],
            vec![],
            vec![(7, 7, 0.5), (7, 8, 0.5)],
        ];
        let mut cfg = Config::preset(Preset::Touch).track;
        cfg.max_trajectories = 2;
        let sampling = Sampling {
            rate_hz: 20.0,
            pitch_mm: 25.4,
            upsample: 7,
        };
        let kept = link_regions(&frames(&movie), &Regions::MEASURED, &cfg, &sampling);
        let first: Vec<usize> = kept.iter().map(|t| t.points[0].frame).collect();
        assert_eq!(first, vec![0, 8]);
    }

    #[test]
    fn a_weak_rim_continues_a_contact_but_starts_none() {
        let weak = vec![(4, 4, 0.05)];
        assert_eq!(count(&[weak.clone(), weak.clone()], 20.0), 0);
        let fading = vec![vec![(4, 4, 0.5)], weak.clone(), weak];
        assert_eq!(count(&fading, 20.0), 1);
    }
}
