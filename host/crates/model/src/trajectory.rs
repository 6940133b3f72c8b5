//! The hand-off between tracking (stage 3) and placement (stage 4).

use serde::{Deserialize, Serialize};

/// One detection on a trajectory.
///
/// The frame is an index after the tare/trim; row and col are pixels of the upsampled,
/// blurred frame (the grid of `touchc track` and the reference JSON).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Frame index.
    pub frame: usize,
    /// Pixel row (y).
    pub row: usize,
    /// Pixel column (x).
    pub col: usize,
    /// Detection cost `ln((1 - P) / P)`.
    pub cost: f64,
    /// Blurred pressure, psi (what an actuator renders).
    pub value: f64,
}

/// One tracked contact: its detections in increasing frame order (consecutive frames,
/// or a few frames apart where a bridge links across flicker).
///
/// In JSON (the output of `touchc track`, the reference vectors) a trajectory is five
/// parallel arrays, `frames`, `rows`, `cols`, `costs` and `values`, as the published code
/// writes it; reading one whose arrays differ in length is an error.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(into = "Columns", try_from = "Columns")]
pub struct Trajectory {
    /// The detections, in increasing frame order.
    pub points: Vec<Point>,
}

impl Trajectory {
    /// Sum of the detection costs (the reference's `total_cost`).
    pub fn total_cost(&self) -> f64 {
        self.points.iter().map(|p| p.cost).sum()
    }

    /// Number of detections.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the trajectory holds no detection.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The detection in frame `t`, if the trajectory has one there.
    pub fn at_frame(&self, t: usize) -> Option<&Point> {
        self.points
            .binary_search_by_key(&t, |p| p.frame)
            .ok()
            .map(|i| &self.points[i])
    }
}

impl FromIterator<Point> for Trajectory {
    fn from_iter<I: IntoIterator<Item = Point>>(points: I) -> Self {
        Trajectory {
            points: points.into_iter().collect(),
        }
    }
}

/// A trajectory as the published code's parallel arrays (its JSON form).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Columns {
    /// Frame index of each detection.
    pub frames: Vec<usize>,
    /// Pixel row of each detection.
    pub rows: Vec<usize>,
    /// Pixel column of each detection.
    pub cols: Vec<usize>,
    /// Detection cost of each detection.
    pub costs: Vec<f64>,
    /// Blurred pressure at each detection, psi.
    pub values: Vec<f64>,
}

/// Parallel arrays of different lengths: not a trajectory.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "trajectory arrays differ in length: frames {frames}, rows {rows}, cols {cols}, \
     costs {costs}, values {values}"
)]
pub struct RaggedColumns {
    /// Length of `frames`.
    pub frames: usize,
    /// Length of `rows`.
    pub rows: usize,
    /// Length of `cols`.
    pub cols: usize,
    /// Length of `costs`.
    pub costs: usize,
    /// Length of `values`.
    pub values: usize,
}

impl Columns {
    /// Number of detections (the length of `frames`).
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when there is no detection.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}

impl TryFrom<Columns> for Trajectory {
    type Error = RaggedColumns;

    fn try_from(c: Columns) -> Result<Self, RaggedColumns> {
        let n = c.frames.len();
        let lengths = [c.rows.len(), c.cols.len(), c.costs.len(), c.values.len()];
        if lengths.iter().any(|&l| l != n) {
            return Err(RaggedColumns {
                frames: n,
                rows: lengths[0],
                cols: lengths[1],
                costs: lengths[2],
                values: lengths[3],
            });
        }
        Ok((0..n)
            .map(|i| Point {
                frame: c.frames[i],
                row: c.rows[i],
                col: c.cols[i],
                cost: c.costs[i],
                value: c.values[i],
            })
            .collect())
    }
}

impl From<Trajectory> for Columns {
    fn from(t: Trajectory) -> Self {
        Columns::from(&t)
    }
}

impl From<&Trajectory> for Columns {
    fn from(t: &Trajectory) -> Self {
        let p = &t.points;
        Columns {
            frames: p.iter().map(|p| p.frame).collect(),
            rows: p.iter().map(|p| p.row).collect(),
            cols: p.iter().map(|p| p.col).collect(),
            costs: p.iter().map(|p| p.cost).collect(),
            values: p.iter().map(|p| p.value).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_is_the_published_parallel_arrays_and_ragged_ones_are_refused() {
        let t: Trajectory = [(3, 1.5), (4, 2.5)]
            .iter()
            .map(|&(frame, value)| Point {
                frame,
                row: frame + 10,
                col: frame + 20,
                cost: -value,
                value,
            })
            .collect();
        let json = serde_json::to_string(&t).unwrap();
        assert_eq!(
            json,
            r#"{"frames":[3,4],"rows":[13,14],"cols":[23,24],"costs":[-1.5,-2.5],"values":[1.5,2.5]}"#
        );
        assert_eq!(serde_json::from_str::<Trajectory>(&json).unwrap(), t);
        assert_eq!(t.at_frame(4).map(|p| p.col), Some(24));
        assert_eq!(t.at_frame(5), None);
        let ragged =
            r#"{"frames":[3,4],"rows":[13],"cols":[23,24],"costs":[-1.5,-2.5],"values":[1.5,2.5]}"#;
        let err = serde_json::from_str::<Trajectory>(ragged).unwrap_err();
        assert!(err.to_string().contains("rows 1"), "{err}");
    }
}
