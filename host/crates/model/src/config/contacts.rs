//! The contact models of real touch: contacts as moving regions ([`Regions`], the `touch`
//! preset's), links across flicker ([`Bridge`]) and flat contacts split on a lattice
//! ([`Split`], the preset's before regions, kept as an option to measure against).

use serde::{Deserialize, Serialize};

/// Contact splitting: a flat contact (a palm) is one blob with a broad top and one local
/// maximum, so one trajectory would stand for all of it and render it at one point.
/// Splitting adds detections on a lattice of cells inside such a contact, so that the
/// actuators it covers each get a trajectory to render.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Split {
    /// A contact is flat when at least this many cells read `level` of its peak or more.
    pub min_cells: usize,
    /// Share of the contact's peak that makes its top.
    pub level: f64,
    /// Lattice pitch, in cells: cells whose row and column are multiples of it. With 2,
    /// every cell of the top lies within 1.5 cells of a lattice cell.
    pub spacing_cells: usize,
    /// Share of a flat contact's peak down to which the lattice covers it (absent: its
    /// top, `level`). Below `level` it reaches the broad, weaker regions a flat hand
    /// presses beside its top (the heel), which are touch the actuators there should play.
    /// Such a point is scored by its contact's peak, weighted by its share of the top.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extent: Option<f64>,
}

impl Split {
    /// The `touch` preset's before contacts were regions (`docs/trade.md` measures
    /// against it): a contact is flat when 8 cells read half its peak, lattice every 2
    /// cells, down to a quarter of the peak. It is used only where `track.regions` is
    /// off.
    pub const LATTICE: Split = Split {
        min_cells: 8,
        level: 0.5,
        spacing_cells: 2,
        extent: Some(0.25),
    };
}

/// Links across missing frames: a contact that reads below detection for a frame or two
/// (sensor flicker) stays one trajectory instead of breaking into pieces.
///
/// A detection in frame `t` also links from detections of frames `t - g` for
/// `g = 2 ..= m + 1`, where `m` frames last at most `max_missing_s`, within `g` times the
/// one-frame gate radius (the contact may keep moving while unseen), at the one-frame
/// link cost of the scaled gate plus `cost_per_missing` per frame skipped. A flow that
/// can take the frames in between keeps them: skipping a strong detection forgoes its
/// negative cost. 100 ms (`touch`) bridges two frames at 20 Hz and five at 54 Hz (real flicker
/// lasts one or two frames at 54 Hz); a lift of 150 ms between two strokes never.
///
/// With bridging, a detection that costs `cost_per_missing` or more is treated as a
/// missing frame and left out of the graph. That gives up nothing the bridge can
/// replace: if a path runs `a -> v -> b` over gaps of `g1` and `g2` frames with
/// `g1 + g2 - 1` within the bridge, the link `a -> b` exists (the gate radius grows
/// with the gap, so `|ab| <= |av| + |vb|` stays inside it) and costs at most
/// `cost_per_missing` more than the two links through `v`, because the link cost
/// `-ln(1 - x)` is convex and increasing in the squared speed `x`; so skipping `v`
/// saves `cost(v) - cost_per_missing >= 0`. A weak detection at either end of a path
/// only adds cost. Only a path that needs `v` to span more than the bridge allows
/// loses it, and then the contact was unseen for longer than a flicker. On real
/// recordings this leaves out the noise maxima (19 of 20 detections on
/// `examples/combination.npy`), which otherwise join every contact within the wide
/// gate and make the flow graph 20 times larger.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bridge {
    /// Longest time a contact may go unseen, seconds.
    pub max_missing_s: f64,
    /// Cost added per frame skipped.
    pub cost_per_missing: f64,
}

impl Bridge {
    /// The most frames a link may skip at `rate_hz`.
    pub fn missing_frames(&self, rate_hz: f64) -> usize {
        let m = (self.max_missing_s * rate_hz + 1e-9).floor();
        if m.is_finite() && m > 0.0 {
            (m as usize).min(MAX_MISSING_FRAMES)
        } else {
            0
        }
    }
}

/// However fast the sensor, a link skips at most this many frames (graph size).
pub(crate) const MAX_MISSING_FRAMES: usize = 16;

/// Contacts as moving regions (`touch`; the paper: none): a contact is the cells a hand
/// presses, tracked as one region with its footprint, not as local maxima linked by
/// min-cost flow.
///
/// On a fabric sensor one hand shows several local maxima per frame, and each cell
/// flickers below the touch threshold for a frame or two; maxima linked frame to frame
/// (or cells fixed on the sensor) make one hand dozens of short trajectories. Here every
/// cell above `footprint_psi` belongs to a region: cells within `join_cells` of each
/// other (a gap of `join_cells - 1` cells, so a flickering cell inside a hand splits
/// nothing) are one region, kept when one of its cells reaches `seed_psi`
/// (hysteresis: the rim of a contact counts, weak noise never starts one). A region
/// continues the contact whose last footprint is nearest (within `join_cells`, or
/// within the link gate `track.max_speed_mm_s` when the contact found no nearer
/// region), and a contact unseen for at most `track.bridge.max_missing_s` goes on
/// (flicker of the whole contact); a lift of 150 ms between two strokes ends it.
/// Each trajectory point is a cell of the footprint, so placement scores what the
/// footprint puts in each circle and an actuator plays the pressure its circle
/// receives from the contact that owns it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Regions {
    /// A region starts where a cell reads at least this, psi.
    pub seed_psi: f64,
    /// Its footprint: the cells above this, psi, joined to such a cell.
    pub footprint_psi: f64,
    /// Cells at most this far apart (the larger of the row and column distance, in
    /// cells) are one region.
    pub join_cells: usize,
}

impl Regions {
    /// The `touch` preset's, measured (`docs/trade.md`, "Real touch on a fabric
    /// grid"): seed at the touch threshold (0.08 psi), footprint at 0.03 psi (ten times
    /// the noise), cells up to 2 apart joined.
    pub const MEASURED: Regions = Regions {
        seed_psi: 0.08,
        footprint_psi: 0.03,
        join_cells: 2,
    };
}
