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
//!
//! Every region of a scene lies on the same few pixels (a contact's cells), so the
//! scene numbers the pixels its footprints cover ([`PixelIndex`]), a transform tests
//! each of them once for all the regions ([`PixelMemo`], small enough to stay in the
//! first-level cache), and a footprint holds only its pixels' numbers and summed costs:
//! an hour of touch has thousands of regions over the same cells, and reading 12 bytes
//! a pixel instead of a whole point is what the scoring of a transform costs.

use super::scoring::{InCircle, Point, Scratch};
use touchc_model::layout::CHANNELS;

/// A region trajectory's distinct pixels and its frames.
pub(super) struct Footprint {
    /// Distinct pixels (their numbers in the scene's [`PixelIndex`]), in order of
    /// first appearance.
    pixels: Vec<u32>,
    /// Per distinct pixel: the summed cost of the trajectory's points there.
    costs: Vec<f64>,
    /// Per frame group: its frame.
    frames: Vec<usize>,
    /// `refs[start[g]..start[g + 1]]` are the pixels group `g` covers.
    start: Vec<usize>,
    /// Indexes into `pixels`.
    refs: Vec<u32>,
}

/// The pixels the scene's footprints cover, numbered in order of first appearance.
#[derive(Default)]
pub(super) struct PixelIndex {
    number: std::collections::HashMap<(usize, usize), u32>,
    /// Per number: the pixel's centre `(x, y)`, mm.
    pub(super) centres: Vec<(f64, f64)>,
}

impl PixelIndex {
    /// The number of `p`'s pixel, given one if it has none yet.
    fn of(&mut self, p: &Point) -> u32 {
        let next = self.centres.len() as u32;
        let n = *self.number.entry((p.row, p.col)).or_insert(next);
        if n == next {
            self.centres.push((p.x, p.y));
        }
        n
    }
}

impl Footprint {
    /// The footprint of `points` (frame order), its pixels numbered in `index`, when
    /// some frame holds two or more of them; `None` for a trajectory with one point a
    /// frame. Only the frames where `shared` holds (another trajectory is present) are
    /// kept as groups: elsewhere nothing can conflict with it.
    pub(super) fn of(
        points: &[Point],
        index: &mut PixelIndex,
        shared: impl Fn(usize) -> bool,
    ) -> Option<Footprint> {
        if !points.windows(2).any(|w| w[0].frame == w[1].frame) {
            return None;
        }
        let mut own = std::collections::HashMap::new();
        let mut fp = Footprint {
            pixels: Vec::new(),
            costs: Vec::new(),
            frames: Vec::new(),
            start: Vec::new(),
            refs: Vec::new(),
        };
        for p in points {
            let keep = shared(p.frame);
            if keep && fp.frames.last() != Some(&p.frame) {
                fp.frames.push(p.frame);
                fp.start.push(fp.refs.len());
            }
            let pixel = index.of(p);
            let i = *own.entry(pixel).or_insert_with(|| {
                fp.pixels.push(pixel);
                fp.costs.push(0.0);
                fp.pixels.len() - 1
            });
            fp.costs[i] += p.cost;
            if keep {
                fp.refs.push(i as u32);
            }
        }
        fp.start.push(fp.refs.len());
        Some(fp)
    }
}

/// Per pixel of the scene's [`PixelIndex`]: the circles of the current transform that
/// hold it and its weight, computed the first time a footprint asks under that
/// transform.
pub(super) struct PixelMemo {
    /// Per pixel: the transform the entry was computed for, its circles and its weight.
    entries: Vec<(u32, u32, f64)>,
    /// The current transform's stamp (never 0, which marks an empty entry).
    stamp: u32,
    /// The pixels' centres, mm.
    centres: Vec<(f64, f64)>,
}

impl PixelMemo {
    /// An empty memo for pixels of these centres.
    pub(super) fn new(centres: &[(f64, f64)]) -> PixelMemo {
        PixelMemo {
            entries: vec![(0, 0, 0.0); centres.len()],
            stamp: 0,
            centres: centres.to_vec(),
        }
    }

    /// Forgets every entry: a new transform.
    pub(super) fn next_transform(&mut self) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.entries.fill((0, 0, 0.0));
            self.stamp = 1;
        }
    }

    /// The circles of `test` that hold `pixel`, and its weight. Every circle is tested:
    /// one that holds a pixel of a trajectory is near that trajectory (its ranges,
    /// with their slack, hold the pixel), so the masks a trajectory would narrow the
    /// test to never drop it.
    #[inline]
    fn get(&mut self, test: &InCircle, pixel: u32) -> (u32, f64) {
        let e = &mut self.entries[pixel as usize];
        if e.0 != self.stamp {
            let (x, y) = self.centres[pixel as usize];
            let pt = Point {
                x,
                y,
                frame: 0,
                cost: 0.0,
                row: 0,
                col: 0,
            };
            let (mask, weight) = test.test(&pt, (1 << CHANNELS) - 1);
            *e = (self.stamp, mask, weight);
        }
        (e.1, e.2)
    }
}

/// [`super::scoring`]'s per-trajectory test for a footprint: whether a pixel lies in a
/// circle and the sum of `cost x weight` over those that do; a candidate's frames with a
/// pixel inside are chained as one hit each, in the circles of all its pixels then.
pub(super) fn footprint_hits(
    test: &InCircle,
    fp: &Footprint,
    candidate: bool,
    s: &mut Scratch,
) -> (bool, f64) {
    let mut masks = std::mem::take(&mut s.pixel_masks);
    masks.clear();
    let mut sum = 0.0;
    let mut inside = false;
    for (&pixel, &cost) in fp.pixels.iter().zip(&fp.costs) {
        let (mask, weight) = s.memo.get(test, pixel);
        if mask != 0 {
            sum += cost * weight;
            inside = true;
        }
        masks.push(mask);
    }
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
