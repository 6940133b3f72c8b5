//! The published transform grid: every placement of the layout that stage 4 scores,
//! in the published order.

use touchc_model::config::{grid_size, PlacementConfig};
use touchc_model::layout::Layout;

use crate::Transform;

/// `numpy.linspace(start, stop, num)` value for value, so that grid points match the
/// published code bit for bit (the last point is `stop` exactly).
pub(super) fn linspace(start: f64, stop: f64, num: usize) -> impl Iterator<Item = f64> {
    let div = num.saturating_sub(1) as f64;
    let delta = stop - start;
    let step = delta / div;
    (0..num).map(move |i| {
        if num == 1 {
            start
        } else if i + 1 == num {
            stop
        } else if step == 0.0 {
            (i as f64 / div) * delta + start
        } else {
            i as f64 * step + start
        }
    })
}

/// The published transform grid, in its order: x outer, then the y index, then the split.
///
/// x runs from "first column's centre half a circle off the near edge" to "last column's
/// centre on the far edge" (`linspace(-18.5, W - 6 * 18.5, 20)` for the paper's sleeve);
/// y over `linspace(0, H, n)`, and for the i-th y the split over
/// `linspace(0, H - y_i, n - i)`, so row 1 never leaves the frame: 4,200 transforms.
pub fn transform_grid(
    frame_rows_px: usize,
    frame_cols_px: usize,
    pitch_mm: f64,
    layout: &Layout,
    cfg: &PlacementConfig,
) -> Vec<Transform> {
    let width = frame_cols_px as f64 * pitch_mm;
    let height = frame_rows_px as f64 * pitch_mm;
    let ws = layout.workspaces();
    let (mut first, mut last) = (ws[0], ws[0]);
    for w in ws {
        if w.x_mm < first.x_mm {
            first = *w;
        }
        if w.x_mm > last.x_mm {
            last = *w;
        }
    }
    let x_lo = -first.radius_mm - first.x_mm;
    let x_hi = width - last.x_mm;
    let ys: Vec<f64> = linspace(0.0, height, cfg.grid_y).collect();
    let mut grid = Vec::with_capacity(grid_size(cfg).unwrap_or(0));
    for x in linspace(x_lo, x_hi, cfg.grid_x) {
        for (i, &y) in ys.iter().enumerate() {
            for split in linspace(0.0, height - y, cfg.grid_y - i) {
                grid.push(Transform {
                    x_mm: x,
                    y_mm: y,
                    scale: 1.0,
                    rotation: 0.0,
                    split_mm: split,
                });
            }
        }
    }
    grid
}

/// Position in grid order of the transform with lattice indices `(ix, iy, is)`:
/// `x` index, `y` index and split index (`is < grid_y - iy`).
pub(super) fn grid_position(grid_y: usize, [ix, iy, is]: [usize; 3]) -> usize {
    let per_x = grid_y * (grid_y + 1) / 2;
    // Splits of the y rows before `iy`: grid_y + (grid_y - 1) + ... (iy terms).
    ix * per_x + iy * grid_y - iy * iy.saturating_sub(1) / 2 + is
}

/// The lattice indices of every grid transform, in grid order (see [`grid_position`]).
pub(super) fn grid_indices(cfg: &PlacementConfig) -> Vec<[usize; 3]> {
    let mut out = Vec::with_capacity(grid_size(cfg).unwrap_or(0));
    for ix in 0..cfg.grid_x {
        for iy in 0..cfg.grid_y {
            for is in 0..cfg.grid_y - iy {
                out.push([ix, iy, is]);
            }
        }
    }
    out
}
