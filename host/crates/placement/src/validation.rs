//! What [`super::place`] refuses before searching: inputs that would make the grid or
//! the scores meaningless.

use touchc_model::config::{grid_size, PlacementConfig, MAX_TRANSFORMS};
use touchc_model::trajectory::Trajectory;

use crate::PlacementError;

pub(super) fn check_inputs(
    trajs: &[Trajectory],
    rows: usize,
    cols: usize,
    pitch_mm: f64,
    cfg: &PlacementConfig,
) -> Result<(), PlacementError> {
    for (field, value) in [("grid_x", cfg.grid_x), ("grid_y", cfg.grid_y)] {
        if value == 0 {
            return Err(PlacementError::InvalidConfig {
                field,
                value: value.to_string(),
                reason: "the grid needs at least one point",
            });
        }
    }
    if grid_size(cfg).is_none_or(|n| n > MAX_TRANSFORMS) {
        return Err(PlacementError::InvalidConfig {
            field: "grid_x * grid_y * (grid_y + 1) / 2",
            value: format!("{} x {}", cfg.grid_x, cfg.grid_y),
            reason: "at most 20,000,000 transforms",
        });
    }
    if let Some(c) = &cfg.coarse_to_fine {
        if c.stride == 0 || c.keep == 0 {
            return Err(PlacementError::InvalidConfig {
                field: "coarse_to_fine",
                value: format!("stride {}, keep {}", c.stride, c.keep),
                reason: "stride and keep must be at least 1",
            });
        }
    }
    if !(cfg.centre_bonus.is_finite() && cfg.centre_bonus >= 0.0) {
        return Err(PlacementError::InvalidConfig {
            field: "centre_bonus",
            value: cfg.centre_bonus.to_string(),
            reason: "must be finite and >= 0 so that every point inside a circle weighs > 0",
        });
    }
    if rows == 0 || cols == 0 {
        return Err(PlacementError::EmptyFrame { rows, cols });
    }
    if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
        return Err(PlacementError::BadPitch(pitch_mm));
    }
    for (t, traj) in trajs.iter().enumerate() {
        for (d, p) in traj.points.iter().enumerate() {
            let (row, col, cost) = (p.row, p.col, p.cost);
            if !cost.is_finite() {
                return Err(PlacementError::NonFiniteCost {
                    trajectory: t,
                    detection: d,
                    cost,
                });
            }
            if let Some(before) = d.checked_sub(1).map(|b| &traj.points[b]) {
                // A footprint's cells share a frame, in row-major order.
                if (p.frame, p.row, p.col) <= (before.frame, before.row, before.col) {
                    let before = before.frame;
                    return Err(PlacementError::FramesNotIncreasing {
                        trajectory: t,
                        detection: d,
                        frame: p.frame,
                        previous: before,
                    });
                }
            }
            if row >= rows || col >= cols {
                return Err(PlacementError::OutsideFrame {
                    trajectory: t,
                    detection: d,
                    row,
                    col,
                    rows,
                    cols,
                });
            }
        }
    }
    Ok(())
}
