//! Stage 2's lattice: the detections a flat contact adds beside its local maxima, one
//! per lattice cell of its top (and, with [`Split::extent`], of its weaker regions).

use ndarray::ArrayView2;

use super::Evidence;
use touchc_model::config::Split;

/// The lattice detections of one blurred frame (`[R k, C k]` pixels, `k = upsample`):
/// the centre pixels of lattice cells inside the top of every flat contact, as
/// `(row, col, value)` in row-major order.
///
/// Cells are read at their centre pixels; a contact is a 4-connected group of cells
/// above `min_value`; its top is the cells at or above `split.level` of its peak.
#[cfg(test)]
pub(super) fn lattice_points(
    frame: ArrayView2<f64>,
    upsample: usize,
    split: &Split,
    min_value: f64,
) -> Vec<(usize, usize, f64)> {
    lattice_points_of_contacts(frame, upsample, split, min_value)
        .into_iter()
        .map(|(p, _)| p)
        .collect()
}

/// `lattice_points`, each with the evidence its detection cost is computed from: its
/// own value on the contact's top; below it (where [`Split::extent`] reaches), the
/// contact's peak, weighted by the point's share of the top's level (`value / top`,
/// between `extent / level` and 1).
///
/// Such a point is part of a contact whose peak shows it is there; scored by its own
/// value, a point on a broad, weaker region (a hand's heel) would cost more than
/// leaving it out, and the region would go untracked. Scored by the peak alone, it
/// would weigh as much as the top in the placement, which picks the transform whose
/// circles hold the most negative cost: the circles would follow a contact's broad rim
/// rather than where it presses. The weight keeps it tracked (half the peak's cost at
/// the extent's floor still pays entry and exit within a few frames) and ranks it below
/// the top, by the pressure it carries.
pub(crate) fn lattice_points_of_contacts(
    frame: ArrayView2<f64>,
    upsample: usize,
    split: &Split,
    min_value: f64,
) -> Vec<((usize, usize, f64), Evidence)> {
    let k = upsample.max(1);
    let (h, w) = frame.dim();
    let (rows, cols) = (h / k, w / k);
    let centre = |i: usize| i * k + k / 2;
    let value = |r: usize, c: usize| frame[[centre(r), centre(c)]];
    let mut label = vec![usize::MAX; rows * cols];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    let spacing = split.spacing_cells.max(1);
    for start in 0..rows * cols {
        if label[start] != usize::MAX
            || value(start / cols, start % cols).partial_cmp(&min_value)
                != Some(std::cmp::Ordering::Greater)
        {
            continue;
        }
        // Flood-fill one contact, remembering its cells and peak.
        let mut cells = Vec::new();
        let mut peak = f64::NEG_INFINITY;
        label[start] = start;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (r, c) = (i / cols, i % cols);
            let v = value(r, c);
            peak = peak.max(v);
            cells.push((i, v));
            let neighbours = [
                (r > 0).then(|| i - cols),
                (r + 1 < rows).then(|| i + cols),
                (c > 0).then(|| i - 1),
                (c + 1 < cols).then(|| i + 1),
            ];
            for j in neighbours.into_iter().flatten() {
                if label[j] == usize::MAX && value(j / cols, j % cols) > min_value {
                    label[j] = start;
                    stack.push(j);
                }
            }
        }
        let top = split.level * peak;
        if cells.iter().filter(|(_, v)| *v >= top).count() < split.min_cells {
            continue;
        }
        let floor = split.extent.map_or(top, |e| e * peak);
        out.extend(
            cells
                .iter()
                .filter(|&&(i, v)| {
                    v >= floor && (i / cols) % spacing == 0 && (i % cols) % spacing == 0
                })
                // A point of the top is scored by its own value; a point the extent
                // adds, by its contact's peak, weighted by its share of the top.
                .map(|&(i, v)| {
                    let evidence = if v >= top {
                        Evidence {
                            fixed: true,
                            ..Evidence::own(v)
                        }
                    } else {
                        Evidence {
                            value: peak,
                            weight: v / top,
                            fixed: true,
                        }
                    };
                    ((centre(i / cols), centre(i % cols), v), evidence)
                }),
        );
    }
    out.sort_by_key(|&((r, c, _), _)| (r, c));
    out
}

/// The local maxima and lattice points of one frame, row-major, each pixel once.
#[cfg(test)]
pub(super) fn with_lattice(
    maxima: Vec<(usize, usize, f64)>,
    lattice: Vec<(usize, usize, f64)>,
) -> Vec<(usize, usize, f64)> {
    if lattice.is_empty() {
        return maxima;
    }
    let mut all = maxima;
    all.extend(lattice);
    all.sort_by_key(|&(r, c, _)| (r, c));
    all.dedup_by_key(|p| (p.0, p.1));
    all
}
