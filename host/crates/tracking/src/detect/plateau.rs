//! Grouping a frame's near-maximum pixels into plateaus, one detection each.

use ndarray::ArrayView2;

use super::{frame_min_of, level};

/// Groups the candidates of [`super::near_maxima`] (row-major) into plateaus and keeps
/// one pixel of each that is above the frame minimum ([`super::local_maxima`]).
pub(super) fn plateaus(
    frame: ArrayView2<f64>,
    candidates: Vec<(usize, usize, f64)>,
) -> Vec<(usize, usize, f64)> {
    let n = candidates.len();
    if n == 0 {
        return candidates;
    }
    let (h, w) = frame.dim();
    let (mut parent, merged) = join_neighbours(&candidates, w);
    let value = |r: usize, c: usize| frame[[r, c]];
    // Whether some in-frame neighbour of (r, c) is lower than it beyond level: then
    // the pixel, and its plateau, is above the frame minimum.
    let has_lower = |r: usize, c: usize, v: f64| {
        (r.saturating_sub(1)..(r + 2).min(h)).any(|rr| {
            (c.saturating_sub(1)..(c + 2).min(w)).any(|cc| {
                let n = value(rr, cc);
                n < v && !level(n, v)
            })
        })
    };
    let mut fmin: Option<f64> = None;
    let mut above_min = |lower: bool, top: f64| {
        lower || {
            let m = *fmin.get_or_insert_with(|| frame_min_of(frame));
            top > m && !level(top, m)
        }
    };
    if !merged {
        // Every plateau one pixel: the common case, no grouping to do.
        let mut out = candidates;
        out.retain(|&(r, c, v)| above_min(has_lower(r, c, v), v));
        return out;
    }
    // Members of each plateau, by root, in row-major order.
    let roots: Vec<usize> = (0..n).map(|i| root(&mut parent, i)).collect();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, &g) in roots.iter().enumerate() {
        members[g].push(i);
    }
    let mut out = Vec::new();
    for group in members.iter().filter(|g| !g.is_empty()) {
        let pts = || group.iter().map(|&i| candidates[i]);
        let top = pts().fold(f64::NEG_INFINITY, |m, p| m.max(p.2));
        if !above_min(pts().any(|(r, c, v)| has_lower(r, c, v)), top) {
            continue;
        }
        out.extend(nearest_centroid(group, &candidates));
    }
    out.sort_by_key(|&(r, c, _)| (r, c));
    out
}

/// The root of `v` in the union-find forest `parent`, halving the path on the way.
fn root(parent: &mut [usize], mut v: usize) -> usize {
    while parent[v] != v {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    v
}

/// Union-find over the row-major `candidates` of a frame `w` pixels wide, joining
/// 8-neighbours: the forest, and whether any two were joined.
fn join_neighbours(candidates: &[(usize, usize, f64)], w: usize) -> (Vec<usize>, bool) {
    // The neighbours already seen are the three above and the one to the left, found
    // through the index of the previous and current rows' candidates by column.
    let mut parent: Vec<usize> = (0..candidates.len()).collect();
    let mut above = vec![usize::MAX; w];
    let mut here = vec![usize::MAX; w];
    let mut touched_above: Vec<usize> = Vec::new();
    let mut touched_here: Vec<usize> = Vec::new();
    let mut row = usize::MAX;
    let mut merged = false;
    for (i, &(r, c, _)) in candidates.iter().enumerate() {
        if r != row {
            for &col in &touched_above {
                above[col] = usize::MAX;
            }
            touched_above.clear();
            if row != usize::MAX && r == row + 1 {
                std::mem::swap(&mut above, &mut here);
                std::mem::swap(&mut touched_above, &mut touched_here);
            } else {
                for &col in &touched_here {
                    here[col] = usize::MAX;
                }
                touched_here.clear();
            }
            row = r;
        }
        let mut link = |j: usize| {
            if j != usize::MAX {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                if a != b {
                    parent[a.max(b)] = a.min(b);
                    merged = true;
                }
            }
        };
        if c > 0 {
            link(here[c - 1]);
        }
        for &j in &above[c.saturating_sub(1)..(c + 2).min(w)] {
            link(j);
        }
        here[c] = i;
        touched_here.push(c);
    }
    (parent, merged)
}

/// The pixel of a plateau (`group` indexes `candidates`, row-major) that stands for it:
/// nearest the centroid, then higher, then first.
fn nearest_centroid(
    group: &[usize],
    candidates: &[(usize, usize, f64)],
) -> Option<(usize, usize, f64)> {
    let pts = || group.iter().map(|&i| candidates[i]);
    let count = group.len() as f64;
    let (sr, sc) = pts().fold((0.0, 0.0), |(a, b), p| (a + p.0 as f64, b + p.1 as f64));
    let (cr, cc) = (sr / count, sc / count);
    let d2 = |p: &(usize, usize, f64)| (p.0 as f64 - cr).powi(2) + (p.1 as f64 - cc).powi(2);
    // `min_by` keeps the first of equals, and the group is in row-major order.
    pts().min_by(|a, b| d2(a).total_cmp(&d2(b)).then(b.2.total_cmp(&a.2)))
}
