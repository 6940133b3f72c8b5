//! What can be wrong with a recording: every variant names the file, so the CLI can
//! print one clear line.

use std::ops::RangeInclusive;

use super::npy;

/// What can be wrong with a recording file or its contents.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The file could not be read at all.
    #[error("{name}: cannot read the file")]
    Io {
        /// The file (or in-memory name) the recording came from.
        name: String,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The bytes are not a well-formed `.npy` file.
    #[error("{name}: not a .npy file ({detail})")]
    NotNpy {
        /// The file the recording came from.
        name: String,
        /// What the parser objected to.
        detail: String,
    },
    /// The header's shape needs more bytes than 64 bits can count.
    #[error("{name}: shape {} of {descr} is too large: its size in bytes overflows 64 bits", npy::shape_str(.shape))]
    TooLarge {
        /// The file the recording came from.
        name: String,
        /// The shape in the header.
        shape: Vec<usize>,
        /// The element type in the header.
        descr: String,
    },
    /// Fewer data bytes follow the header than its shape needs.
    #[error("{name}: truncated: shape {} of {descr} needs {needed} bytes of data, the file holds {found}", npy::shape_str(.shape))]
    Truncated {
        /// The file the recording came from.
        name: String,
        /// The shape in the header.
        shape: Vec<usize>,
        /// The element type in the header.
        descr: String,
        /// Data bytes the shape needs.
        needed: u64,
        /// Data bytes present.
        found: u64,
    },
    /// More data bytes follow the header than its shape needs.
    #[error("{name}: {} unexpected bytes after the data: shape {} of {descr} needs {needed} bytes, the file holds {found}", .found - .needed, npy::shape_str(.shape))]
    TrailingBytes {
        /// The file the recording came from.
        name: String,
        /// The shape in the header.
        shape: Vec<usize>,
        /// The element type in the header.
        descr: String,
        /// Data bytes the shape needs.
        needed: u64,
        /// Data bytes present.
        found: u64,
    },
    /// A stream's `.npy` header claims more data than a stream may bring
    /// ([`STREAM_BUDGET_BYTES`](super::STREAM_BUDGET_BYTES)); refused before it is read.
    #[error("{name}: shape {} needs {needed} bytes, more than the {budget} bytes read from a stream", npy::shape_str(.shape))]
    StreamClaimTooLarge {
        /// The stream the recording came from.
        name: String,
        /// The shape in the header.
        shape: Vec<usize>,
        /// Bytes the header and its shape need.
        needed: u64,
        /// The budget ([`STREAM_BUDGET_BYTES`](super::STREAM_BUDGET_BYTES)).
        budget: u64,
    },
    /// A stream carries an archive longer than a stream may bring
    /// ([`STREAM_BUDGET_BYTES`](super::STREAM_BUDGET_BYTES)).
    #[error("{name}: the archive goes on past the {budget} bytes read from a stream")]
    StreamTooLong {
        /// The stream the recording came from.
        name: String,
        /// The budget ([`STREAM_BUDGET_BYTES`](super::STREAM_BUDGET_BYTES)).
        budget: u64,
    },
    /// The file is text (a CSV, a JSON export), not a `.npy` or `.npz` file.
    #[error("{name}: text, not a .npy or .npz file (it starts with {start:?})")]
    Text {
        /// The file the recording came from.
        name: String,
        /// Its first characters, up to a line.
        start: String,
    },
    /// The bytes look like a zip archive but cannot be read as one.
    #[error("{name}: not a readable .npz archive ({detail})")]
    NotNpz {
        /// The file the recording came from.
        name: String,
        /// What the zip reader objected to.
        detail: String,
    },
    /// The archive has no `pressure` array.
    #[error("{name}: no array named 'pressure' in the archive (it holds {found})")]
    MissingPressure {
        /// The file the recording came from.
        name: String,
        /// The entries it does hold, quoted.
        found: String,
    },
    /// An archive entry declares another uncompressed size than its header needs.
    #[error("{name}: entry {entry:?} declares {declared} bytes uncompressed but its header needs {needed} (a zip bomb or a corrupt archive)")]
    EntrySize {
        /// The file the recording came from.
        name: String,
        /// The entry's name in the archive.
        entry: String,
        /// The uncompressed size the archive declares.
        declared: u64,
        /// The size the entry's `.npy` header and shape need.
        needed: u64,
    },
    /// An archive entry decompresses to more than its header needs.
    #[error("{name}: entry {entry:?} decompresses to more than the {needed} bytes its header needs (a zip bomb or a corrupt archive)")]
    Inflated {
        /// The file the recording came from.
        name: String,
        /// The entry's name in the archive.
        entry: String,
        /// The size the entry's `.npy` header and shape need.
        needed: u64,
    },
    /// An archive entry needs more memory, decompressed, than an entry may take
    /// ([`MEMBER_BUDGET_BYTES`](super::MEMBER_BUDGET_BYTES)); refused before it is inflated.
    #[error("{name}: entry {entry:?} needs {needed} bytes decompressed, more than the {budget} bytes an archive entry may take (an archive's sizes can claim far more than its file holds)")]
    MemberTooLarge {
        /// The file the recording came from.
        name: String,
        /// The entry's name in the archive.
        entry: String,
        /// The size the entry's `.npy` header and shape need.
        needed: u64,
        /// The budget ([`MEMBER_BUDGET_BYTES`](super::MEMBER_BUDGET_BYTES)).
        budget: u64,
    },
    /// The memory for an archive entry's data could not be had.
    #[error("{name}: entry {entry:?}: out of memory after {read} of the {needed} bytes it needs decompressed")]
    OutOfMemory {
        /// The file the recording came from.
        name: String,
        /// The entry's name in the archive.
        entry: String,
        /// Bytes read when the allocation failed.
        read: u64,
        /// The size the entry's `.npy` header and shape need.
        needed: u64,
    },
    /// The archive holds many end-of-directory records, which only a crafted file does.
    #[error("{name}: not a readable .npz archive: it holds {found} zip end-of-central-directory records (numpy writes one); refused rather than tried one by one")]
    EndRecords {
        /// The file the recording came from.
        name: String,
        /// End records found.
        found: usize,
    },
    /// A metadata entry is not a single number.
    #[error(
        "{name}: {field} must be a single number (a 0-d float or integer array), found {found}"
    )]
    BadMetadata {
        /// The file the recording came from.
        name: String,
        /// `rate_hz` or `pitch_mm`.
        field: &'static str,
        /// What the entry holds instead.
        found: String,
    },
    /// A metadata value is not finite or outside its plausible range.
    #[error("{name}: {field} = {} is outside the plausible range {} to {} {unit}", touchc_model::display::Shortest(*.value), .range.start(), .range.end())]
    MetadataRange {
        /// The file the recording came from.
        name: String,
        /// `rate_hz` or `pitch_mm`.
        field: &'static str,
        /// The value found.
        value: f64,
        /// The range accepted ([`RATE_HZ_RANGE`](touchc_model::config::RATE_HZ_RANGE), [`PITCH_MM_RANGE`](touchc_model::config::PITCH_MM_RANGE)).
        range: RangeInclusive<f64>,
        /// The unit of the value.
        unit: &'static str,
    },
    /// The array holds something other than float32, float64 or integers.
    #[error("{name}: unsupported element type {descr}; expected float32, float64 or integers")]
    UnsupportedDtype {
        /// The file the recording came from.
        name: String,
        /// The `.npy` type descriptor found in the header.
        descr: String,
    },
    /// The array is not three-dimensional.
    #[error("{name}: expected a 3-D array [frames, rows, cols], found {ndim} dimension(s)")]
    WrongRank {
        /// The file the recording came from.
        name: String,
        /// Number of dimensions found.
        ndim: usize,
    },
    /// One of the axes has length zero.
    #[error("{name}: empty recording, shape {shape:?} has a zero-length axis")]
    Empty {
        /// The file the recording came from.
        name: String,
        /// The shape found.
        shape: [usize; 3],
    },
    /// Every value is NaN: the recording has no sensor cell at all.
    #[error("{name}: every value is NaN (no sensor cell in any frame)")]
    AllNan {
        /// The file the recording came from.
        name: String,
    },
    /// A value is +inf or -inf (a sensor glitch or a unit error upstream).
    #[error("{name}: infinite value at frame {frame}, row {row}, col {col}")]
    Infinite {
        /// The file the recording came from.
        name: String,
        /// Frame of the first infinite value.
        frame: usize,
        /// Row of the first infinite value.
        row: usize,
        /// Column of the first infinite value.
        col: usize,
    },
    /// Too few frames to tare and still keep one frame.
    #[error(
        "{name}: {frames} frame(s) is too short: the tare window ({tare} frames) and the \
         trim at each end need at least {min} frames"
    )]
    TooShort {
        /// The file the recording came from.
        name: String,
        /// Frames in the recording.
        frames: usize,
        /// The tare buffer `B`.
        tare: usize,
        /// The minimum number of frames, `2 B + 1`.
        min: usize,
    },
}
