//! The bounds a config and a recording are held to, shared by validation and the stages
//! that rely on them.

use std::ops::RangeInclusive;

use super::PlacementConfig;

/// Frame rates a recording may have, in Hz: from a slow pressure mat up to the sleeve's
/// 1 kHz output rate, which a recording's frames are resampled to (the player has no
/// faster ticks to play more frames on). Outside this the value is more likely a unit
/// mistake (a period, kHz) than a sensor.
pub const RATE_HZ_RANGE: RangeInclusive<f64> = 1.0..=1_000.0;

/// Cell pitches a file may declare, in mm: from e-skin taxels to a coarse seat mat.
pub const PITCH_MM_RANGE: RangeInclusive<f64> = 0.1..=100.0;

/// The largest upsampling factor: x32 already makes a 705-frame recording 1.3 GB of f64
/// pixels, and detections finer than 0.8 mm mean nothing on a one-inch sensor.
pub const MAX_UPSAMPLE: usize = 32;

/// Transforms in the grid of `cfg` (`grid_x * grid_y * (grid_y + 1) / 2`); `None` if that
/// overflows.
pub fn grid_size(cfg: &PlacementConfig) -> Option<usize> {
    let per_x = cfg.grid_y.checked_mul(cfg.grid_y.checked_add(1)?)? / 2;
    cfg.grid_x.checked_mul(per_x)
}

/// The largest grid placement accepts: 2 million transforms, 33 times the `exact`
/// preset's 60 060. A grid of 20 million cost 12 s and 1.6 GB on a 10 s recording
/// (`--set placement.grid_x=20000000 --set placement.grid_y=1`) and no placement needs
/// one (the grid converges well before, see `docs/trade.md`).
pub const MAX_TRANSFORMS: usize = 2_000_000;

/// The most steps along one axis of the placement grid: 10 000 steps put positions
/// 0.05 mm apart along the paper's 533 mm sleeve, far below what a 25.4 mm sensor
/// cell can tell apart.
pub const MAX_GRID_STEPS: usize = 10_000;
