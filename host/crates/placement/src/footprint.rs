//! Trajectories of moving regions (several points a frame: the cells of a contact's
//! footprint) as placement scores them: once per distinct pixel, not once per point.
//!
//! A region tracked for a minute revisits the same few dozen cells thousands of times.
//! Its score under a transform is the sum over its points of `cost x weight(pixel)`,
//! that is the sum over its distinct pixels of `weight(pixel) x` the summed cost of
//! the points there; and its workspaces in a frame are those of the pixels it covers
//! then. So each transform tests each distinct pixel once, then ORs bit masks per
//! frame. Trajectories with one point a frame (every preset but `touch`) keep the
//! published per-point sums, bit for bit.

use super::scoring::{InCircle, Point, Scratch};

/// A region trajectory's distinct pixels and its frames.
pub(super) struct Footprint {
    /// Distinct pixels, in order of first appearance, each with the summed cost of the
    /// trajectory's points there.
    pub(super) pixels: Vec<Point>,
    /// Per frame group: its frame.
    frames: Vec<usize>,
    /// `refs[start[g]..start[g + 1]]` are the pixels group `g` covers.
    start: Vec<usize>,
    /// Indexes into `pixels`.
    refs: Vec<u32>,
}

impl Footprint {
    /// The footprint of `points` (frame order) when some frame holds two or more of
    /// them; `None` for a trajectory with one point a frame. Only the frames where
    /// `shared` holds (another trajectory is present) are kept as groups: elsewhere
    /// nothing can conflict with it.
    pub(super) fn of(points: &[Point], shared: impl Fn(usize) -> bool) -> Option<Footprint> {
        if !points.windows(2).any(|w| w[0].frame == w[1].frame) {
            return None;
        }
        let mut index = std::collections::HashMap::new();
        let mut fp = Footprint {
            pixels: Vec::new(),
            frames: Vec::new(),
            start: Vec::new(),
            refs: Vec::with_capacity(points.len()),
        };
        for p in points {
            let keep = shared(p.frame);
            if keep && fp.frames.last() != Some(&p.frame) {
                fp.frames.push(p.frame);
                fp.start.push(fp.refs.len());
            }
            let i = *index.entry((p.row, p.col)).or_insert_with(|| {
                fp.pixels.push(Point { cost: 0.0, ..*p });
                fp.pixels.len() - 1
            });
            fp.pixels[i].cost += p.cost;
            if keep {
                fp.refs.push(i as u32);
            }
        }
        fp.start.push(fp.refs.len());
        Some(fp)
    }
}

/// [`super::scoring`]'s per-trajectory test for a footprint: whether a pixel lies in a
/// circle and the sum of `cost x weight` over those that do; a candidate's frames with a
/// pixel inside are chained as one hit each, in the circles of all its pixels then.
pub(super) fn footprint_hits(
    test: &InCircle,
    fp: &Footprint,
    near: u32,
    per_point: bool,
    candidate: bool,
    s: &mut Scratch,
) -> (bool, f64) {
    let mut masks = std::mem::take(&mut s.pixel_masks);
    masks.clear();
    let mut sum = 0.0;
    for px in &fp.pixels {
        let bits = if per_point {
            near & s.col_mask[px.col] & s.row_mask[px.row]
        } else {
            near
        };
        let (mask, weight) = test.test(px, bits);
        if mask != 0 {
            sum += px.cost * weight;
        }
        masks.push(mask);
    }
    let inside = masks.iter().any(|&m| m != 0);
    if candidate && inside {
        for (g, &frame) in fp.frames.iter().enumerate() {
            let refs = &fp.refs[fp.start[g]..fp.start[g + 1]];
            let mask = refs.iter().fold(0, |m, &i| m | masks[i as usize]);
            if mask != 0 {
                s.push_hit(frame, mask);
            }
        }
    }
    s.pixel_masks = masks;
    (inside, sum)
}
