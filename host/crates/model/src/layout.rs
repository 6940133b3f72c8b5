//! The actuator layout as data: where each workspace circle sits on the sleeve.
//!
//! The paper's sleeve is built in (`layouts/paper.toml`, compiled into the binary), and a
//! user may replace it with their own TOML file of the same shape: one `[[workspace]]`
//! table per actuator. The count is fixed at [`CHANNELS`] (2 rows x 4 columns) because the
//! stimulus format and the firmware drive exactly that many channels; the geometry within
//! that grid (centres, radii, weights) is free.
//!
//! Coordinates are in mm in the layout's own frame: x along the arm (column 0 nearest the
//! elbow), y across it. Placement translates the whole layout onto the recording's frame
//! and may move row 1 relative to row 0 (the vertical split).

use std::path::Path;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::geometry::Circle;

/// Actuator channels on the sleeve (and in the stimulus file): the protocol's count.
pub const CHANNELS: usize = touch_protocol::CHANNELS;
/// Rows of workspaces; the vertical split moves row `r` by `r * split`.
pub const ROWS: usize = 2;
/// Workspaces per row; `channel = row * COLUMNS + column`.
pub const COLUMNS: usize = 4;

// The grid of workspaces covers every channel of the protocol once.
const _: () = assert!(ROWS * COLUMNS == CHANNELS);

/// The built-in paper layout, kept as a file so that users can copy and edit it.
const PAPER_TOML: &str = include_str!("../../../layouts/paper.toml");
/// Name used in error messages for the built-in layout.
const PAPER_ORIGIN: &str = "<built-in layouts/paper.toml>";

/// The most bytes of a layout file read: eight actuators take a few hundred.
pub const MAX_LAYOUT_BYTES: u64 = 1 << 20;

/// One actuator's workspace, as written in the layout file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Workspace {
    /// Output channel; must equal `row * 4 + column` so that wiring and geometry agree.
    pub channel: usize,
    /// Row, 0 or 1; the vertical split of a transform moves row 1 only.
    pub row: usize,
    /// Column, 0 (nearest the elbow) to 3; neighbour fill works along a row.
    pub column: usize,
    /// Centre along the arm in the layout's frame, mm.
    pub x_mm: f64,
    /// Centre across the arm in the layout's frame, mm.
    pub y_mm: f64,
    /// How far the actuator centre may be from a trajectory point and still render it, mm.
    pub radius_mm: f64,
    /// Placement weight `w_a`: biases the search towards placing trajectories here.
    pub weight: f64,
}

/// A validated layout: exactly [`CHANNELS`] workspaces, in channel order.
///
/// Fields are private so that every `Layout` in the program has passed validation.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    id: String,
    description: Option<String>,
    workspaces: [Workspace; CHANNELS],
}

/// The on-disk shape of a layout file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutFile {
    id: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    workspace: Vec<Workspace>,
}

/// Why a layout could not be read, parsed or accepted. Every variant names its origin
/// (a path, or the built-in layout) so that the user knows which file to fix.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// The file could not be read.
    #[error("{origin}: cannot read the layout file: {source}")]
    Read {
        /// File the layout came from.
        origin: String,
        /// The I/O failure.
        #[source]
        source: std::io::Error,
    },
    /// The text is not TOML of the layout's shape.
    #[error("{origin}: not a valid layout file: {source}")]
    Parse {
        /// File the layout came from.
        origin: String,
        /// The TOML parser's account, with line and column.
        #[source]
        source: toml::de::Error,
    },
    /// The layout has no id, so results could not say which sleeve they were made for.
    #[error("{origin}: the layout id is empty")]
    EmptyId {
        /// File the layout came from.
        origin: String,
    },
    /// The id is longer than a stimulus can carry.
    #[error("{origin}: the layout id is {len} bytes long; stimuli carry at most {max}")]
    IdTooLong {
        /// File the layout came from.
        origin: String,
        /// Bytes of UTF-8 in the id.
        len: usize,
        /// [`touch_protocol::layout::MAX_NAME_LEN`].
        max: usize,
    },
    /// Not exactly one workspace per channel.
    #[error(
        "{origin}: expected {expected} [[workspace]] entries (2 rows x 4 columns), found {found}"
    )]
    WorkspaceCount {
        /// File the layout came from.
        origin: String,
        /// Workspaces required.
        expected: usize,
        /// Workspaces present.
        found: usize,
    },
    /// A workspace lies outside the 2 x 4 grid.
    #[error("{origin}: workspace #{index}: row {row}, column {column} is outside the 2 x 4 grid")]
    OutOfGrid {
        /// File the layout came from.
        origin: String,
        /// Position of the entry in the file (0-based).
        index: usize,
        /// Row given.
        row: usize,
        /// Column given.
        column: usize,
    },
    /// The channel does not follow `row * 4 + column`.
    #[error("{origin}: workspace #{index}: channel {channel}, but row * 4 + column = {expected}")]
    ChannelMismatch {
        /// File the layout came from.
        origin: String,
        /// Position of the entry in the file (0-based).
        index: usize,
        /// Channel given.
        channel: usize,
        /// Channel implied by row and column.
        expected: usize,
    },
    /// Two workspaces claim the same channel.
    #[error("{origin}: workspace #{index}: channel {channel} is already used by an earlier entry")]
    DuplicateChannel {
        /// File the layout came from.
        origin: String,
        /// Position of the second entry in the file (0-based).
        index: usize,
        /// The repeated channel.
        channel: usize,
    },
    /// A coordinate, radius or weight is NaN or infinite.
    #[error("{origin}: workspace #{index}: {field} = {value} is not a finite number")]
    NonFinite {
        /// File the layout came from.
        origin: String,
        /// Position of the entry in the file (0-based).
        index: usize,
        /// Field name as in the file.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// A radius or weight is zero or negative.
    #[error("{origin}: workspace #{index}: {field} = {} must be positive", crate::display::Shortest(*.value))]
    NonPositive {
        /// File the layout came from.
        origin: String,
        /// Position of the entry in the file (0-based).
        index: usize,
        /// Field name as in the file.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// The layout could not be written as TOML.
    #[error("cannot write layout as TOML")]
    Serialize(#[from] toml::ser::Error),
}

impl Layout {
    /// The sleeve of the paper, the default for every command.
    pub fn paper() -> Layout {
        match Layout::from_toml_str(PAPER_TOML, PAPER_ORIGIN) {
            Ok(layout) => layout,
            // Not reachable from user data: the built-in file is pinned by a unit test.
            Err(e) => panic!("built-in layout is invalid: {e}"),
        }
    }

    /// Parses and validates a layout; `origin` names the source in error messages.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Layout, LayoutError> {
        let file: LayoutFile = toml::from_str(text).map_err(|source| LayoutError::Parse {
            origin: origin.to_owned(),
            source,
        })?;
        Self::validate(file, origin)
    }

    /// Reads a layout file, at most [`MAX_LAYOUT_BYTES`] of it (a device or a pipe,
    /// `/dev/zero`, could go on for ever).
    pub fn load(path: &Path) -> Result<Layout, LayoutError> {
        use std::io::Read;
        let origin = path.display().to_string();
        let read = |source| LayoutError::Read {
            origin: origin.clone(),
            source,
        };
        let mut text = String::new();
        std::fs::File::open(path)
            .map_err(read)?
            .take(MAX_LAYOUT_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(read)?;
        if text.len() as u64 > MAX_LAYOUT_BYTES {
            return Err(read(std::io::Error::other(format!(
                "more than {MAX_LAYOUT_BYTES} bytes, far more than a layout file holds"
            ))));
        }
        Self::from_toml_str(&text, &origin)
    }

    /// The layout as a TOML file that [`Layout::from_toml_str`] reads back unchanged.
    pub fn to_toml_string(&self) -> Result<String, LayoutError> {
        let file = LayoutFile {
            id: self.id.clone(),
            description: self.description.clone(),
            workspace: self.workspaces.to_vec(),
        };
        Ok(toml::to_string(&file)?)
    }

    /// Identifies the sleeve a stimulus was placed for (stored with results).
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The hash of the layout's geometry that stimuli and banks carry
    /// ([`touch_protocol::layout::geometry_hash`]): channel order, centres relative to
    /// channel 0 and radii, in whole micrometres. Weights are a placement preference,
    /// not geometry, and do not enter it.
    pub fn geometry_hash(&self) -> u32 {
        let um = |mm: f64| (mm * 1000.0).round() as i32;
        touch_protocol::layout::geometry_hash(&self.workspaces.map(|w| {
            touch_protocol::layout::Actuator {
                x_um: um(w.x_mm),
                y_um: um(w.y_mm),
                radius_um: um(w.radius_mm),
            }
        }))
    }

    /// Free-text description from the file, if any.
    pub fn description(&self) -> Option<&str> {
        self.description.as_deref()
    }

    /// Workspaces in channel order.
    pub fn workspaces(&self) -> &[Workspace; CHANNELS] {
        &self.workspaces
    }

    /// The workspace circles untransformed, in channel order (the layout's own frame).
    pub fn circles(&self) -> [Circle; CHANNELS] {
        self.workspaces.map(|w| Circle {
            x_mm: w.x_mm,
            y_mm: w.y_mm,
            r_mm: w.radius_mm,
            weight: w.weight,
        })
    }

    fn validate(file: LayoutFile, origin: &str) -> Result<Layout, LayoutError> {
        let origin_s = || origin.to_owned();
        if file.id.trim().is_empty() {
            return Err(LayoutError::EmptyId { origin: origin_s() });
        }
        if file.id.len() > touch_protocol::layout::MAX_NAME_LEN {
            return Err(LayoutError::IdTooLong {
                origin: origin_s(),
                len: file.id.len(),
                max: touch_protocol::layout::MAX_NAME_LEN,
            });
        }
        if file.workspace.len() != CHANNELS {
            return Err(LayoutError::WorkspaceCount {
                origin: origin_s(),
                expected: CHANNELS,
                found: file.workspace.len(),
            });
        }
        let mut slots: [Option<Workspace>; CHANNELS] = [None; CHANNELS];
        for (index, w) in file.workspace.iter().enumerate() {
            if w.row >= ROWS || w.column >= COLUMNS {
                return Err(LayoutError::OutOfGrid {
                    origin: origin_s(),
                    index,
                    row: w.row,
                    column: w.column,
                });
            }
            let expected = w.row * COLUMNS + w.column;
            if w.channel != expected {
                return Err(LayoutError::ChannelMismatch {
                    origin: origin_s(),
                    index,
                    channel: w.channel,
                    expected,
                });
            }
            for (field, value) in [
                ("x_mm", w.x_mm),
                ("y_mm", w.y_mm),
                ("radius_mm", w.radius_mm),
                ("weight", w.weight),
            ] {
                if !value.is_finite() {
                    return Err(LayoutError::NonFinite {
                        origin: origin_s(),
                        index,
                        field,
                        value,
                    });
                }
            }
            for (field, value) in [("radius_mm", w.radius_mm), ("weight", w.weight)] {
                if value <= 0.0 {
                    return Err(LayoutError::NonPositive {
                        origin: origin_s(),
                        index,
                        field,
                        value,
                    });
                }
            }
            let slot = &mut slots[w.channel];
            if slot.is_some() {
                return Err(LayoutError::DuplicateChannel {
                    origin: origin_s(),
                    index,
                    channel: w.channel,
                });
            }
            *slot = Some(*w);
        }
        // Eight entries with eight distinct channels in 0..8 fill every slot.
        let mut workspaces = [file.workspace[0]; CHANNELS];
        for (dst, src) in workspaces.iter_mut().zip(slots) {
            if let Some(w) = src {
                *dst = w;
            }
        }
        Ok(Layout {
            id: file.id,
            description: file.description,
            workspaces,
        })
    }
}

impl Default for Layout {
    fn default() -> Self {
        Layout::paper()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_layout_matches_the_published_geometry() {
        let layout = Layout::paper();
        assert_eq!(layout.id(), "paper-2x4");
        for (ch, w) in layout.workspaces().iter().enumerate() {
            assert_eq!(w.channel, ch);
            assert_eq!(w.row, ch / 4);
            assert_eq!(w.column, ch % 4);
            assert_eq!(w.x_mm, 37.0 * w.column as f64);
            assert_eq!(w.y_mm, 50.0 * w.row as f64);
            assert_eq!(w.radius_mm, 18.5);
            assert_eq!(w.weight, if w.column == 1 { 1.02 } else { 1.0 });
        }
    }

    #[test]
    fn the_built_in_layout_is_the_sleeve_the_firmware_drives() {
        let layout = Layout::paper();
        assert_eq!(layout.geometry_hash(), touch_protocol::layout::SLEEVE_HASH);
        assert_eq!(layout.id(), touch_protocol::layout::SLEEVE_NAME);
    }

    #[test]
    fn a_layout_id_longer_than_a_stimulus_carries_is_refused() {
        let text = Layout::paper()
            .to_toml_string()
            .unwrap()
            .replace("paper-2x4", &"x".repeat(25));
        let err = Layout::from_toml_str(&text, "long.toml").unwrap_err();
        assert!(
            matches!(
                err,
                LayoutError::IdTooLong {
                    len: 25,
                    max: 24,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn toml_round_trip_is_exact() {
        let layout = Layout::paper();
        let text = layout.to_toml_string().unwrap();
        let back = Layout::from_toml_str(&text, "round-trip").unwrap();
        assert_eq!(back, layout);
    }

    #[test]
    fn load_reads_a_file_and_reports_its_path() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("sleeve.toml");
        std::fs::write(&good, Layout::paper().to_toml_string().unwrap()).unwrap();
        assert_eq!(Layout::load(&good).unwrap(), Layout::paper());

        let missing = dir.path().join("missing.toml");
        let err = Layout::load(&missing).unwrap_err();
        assert!(matches!(err, LayoutError::Read { .. }));
        assert!(err.to_string().contains("missing.toml"), "{err}");
    }

    /// Entries are accepted in any order and stored in channel order.
    #[test]
    fn entries_are_sorted_by_channel() {
        let mut file: LayoutFile = toml::from_str(PAPER_TOML).unwrap();
        file.workspace.reverse();
        let text = toml::to_string(&file).unwrap();
        assert_eq!(
            Layout::from_toml_str(&text, "reversed").unwrap(),
            Layout::paper()
        );
    }

    fn edited(edit: impl FnOnce(&mut LayoutFile)) -> Result<Layout, LayoutError> {
        let mut file: LayoutFile = toml::from_str(PAPER_TOML).unwrap();
        edit(&mut file);
        Layout::from_toml_str(&toml::to_string(&file).unwrap(), "bad.toml")
    }

    #[test]
    fn bad_layouts_are_rejected_with_the_file_and_the_problem() {
        let cases: Vec<(Result<Layout, LayoutError>, &str)> = vec![
            (edited(|f| f.id = " ".into()), "id is empty"),
            (edited(|f| f.workspace.truncate(7)), "found 7"),
            (
                edited(|f| {
                    let w = f.workspace[0];
                    f.workspace.push(w)
                }),
                "found 9",
            ),
            (
                edited(|f| f.workspace[2].column = 4),
                "outside the 2 x 4 grid",
            ),
            (edited(|f| f.workspace[2].row = 2), "outside the 2 x 4 grid"),
            (
                edited(|f| f.workspace[3].channel = 5),
                "channel 5, but row * 4 + column = 3",
            ),
            (
                edited(|f| {
                    f.workspace[3].column = 2;
                    f.workspace[3].channel = 2;
                }),
                "channel 2 is already used",
            ),
            (
                edited(|f| f.workspace[1].radius_mm = 0.0),
                "radius_mm = 0 must be positive",
            ),
            (
                edited(|f| f.workspace[1].weight = -1.0),
                "weight = -1 must be positive",
            ),
            (
                edited(|f| f.workspace[4].x_mm = f64::INFINITY),
                "x_mm = inf is not a finite",
            ),
            (
                edited(|f| f.workspace[4].y_mm = f64::NAN),
                "y_mm = NaN is not a finite",
            ),
        ];
        for (result, needle) in cases {
            let msg = result.unwrap_err().to_string();
            assert!(msg.starts_with("bad.toml: "), "{msg}");
            assert!(msg.contains(needle), "{msg:?} should contain {needle:?}");
        }
    }

    #[test]
    fn parse_errors_name_the_file() {
        let err =
            Layout::from_toml_str("id = \"x\"\n[[workspace]]\nchannel = \"zero\"\n", "my.toml")
                .unwrap_err();
        assert!(matches!(err, LayoutError::Parse { .. }));
        assert!(
            err.to_string()
                .starts_with("my.toml: not a valid layout file"),
            "{err}"
        );
        let err = Layout::from_toml_str("id = \"x\"\nunknown = 1\nworkspace = []\n", "my.toml")
            .unwrap_err();
        assert!(err.to_string().contains("unknown"), "{err}");
    }
}
