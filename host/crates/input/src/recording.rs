//! Stage 0: load a pressure-sleeve recording and tare it.
//!
//! A recording is an array `[T, rows, cols]` of psi at the sensor frame rate, with NaN
//! for "no sensor cell" (the public data set pads every frame to 8 x 21 cells), either as
//! a `.npy` file or as a numpy `.npz` archive holding it as `pressure` beside optional
//! scalars `rate_hz` and `pitch_mm`. The format is told by the content, not the name.
//! Everything a user can get wrong about the file is a typed [`RecordingError`] that
//! names the file, so the CLI can print one clear line.
//!
//! Reading is bounded by the file: the header is checked against the bytes that follow
//! it before anything is allocated (see `npy.rs`), and an archive entry is decompressed
//! only up to the size its own header says it needs (see `npz.rs`).

use std::path::Path;

use ndarray::{Array3, ArrayView3};

use touchc_model::config::{FileMetadata, PITCH_MM_RANGE, RATE_HZ_RANGE};

mod errors;
mod npy;
mod npz;
mod stream;
mod tare;

pub use errors::RecordingError;
pub use stream::STREAM_BUDGET_BYTES;
pub(crate) use tare::map_cell_series;

/// The most bytes one `.npz` entry may need decompressed: 512 MiB, eleven hours of an
/// 8 x 21 float32 recording at 20 Hz. An archive's declared sizes cost nothing to
/// write (1 MB of deflate inflates to 1 GB), so unlike a `.npy` file, whose size is on
/// the disk, an entry is checked against this before it is inflated; and its data is
/// read in pieces whose memory is asked for fallibly, so a process that cannot get it
/// reports [`RecordingError::OutOfMemory`] instead of aborting.
pub const MEMBER_BUDGET_BYTES: u64 = 1 << 29;

/// A validated recording: raw psi, NaN where there is no sensor cell.
///
/// Stored as f64 whatever the file held, because the global statistics downstream are
/// accumulated in f64 and an f32 file converts exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    name: String,
    data: Array3<f64>,
    rate_hz: Option<f64>,
    pitch_mm: Option<f64>,
}

impl Recording {
    /// Loads and validates a `.npy` file (float32, float64 or integers, either byte
    /// order, C or Fortran order) or a numpy `.npz` archive (`savez` or `savez_compressed`) holding
    /// such an array as `pressure`, with optional scalars `rate_hz` and `pitch_mm`. The
    /// format is told by the first bytes, whatever the file is called.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, RecordingError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let io = |source| RecordingError::Io {
            name: name.clone(),
            source,
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        if !file.metadata().map_err(io)?.is_file() {
            // A device or a pipe (`/dev/zero`, `<(...)`): it may never end.
            return Self::read_from(name.clone(), &mut file);
        }
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut file, &mut bytes).map_err(io)?;
        Self::from_bytes(name, &bytes)
    }

    /// Reads a `.npy` or `.npz` recording from a stream (standard input, a pipe, a
    /// device), bounded: the magic number is checked first, a `.npy` is read up to the
    /// data its header claims, and nothing more than [`STREAM_BUDGET_BYTES`] is read.
    /// `name` is used in errors.
    pub fn read_from(
        name: impl Into<String>,
        reader: &mut dyn std::io::Read,
    ) -> Result<Self, RecordingError> {
        let name = name.into();
        let bytes = stream::read_bounded(&name, reader)?;
        Self::from_bytes(name, &bytes)
    }

    /// Parses and validates the bytes of a `.npy` or `.npz` file, told apart by their
    /// magic numbers; `name` is used in errors.
    pub fn from_bytes(name: impl Into<String>, bytes: &[u8]) -> Result<Self, RecordingError> {
        let name = name.into();
        if npz::is_zip(bytes) {
            Self::from_npz_bytes(name, bytes)
        } else if bytes.starts_with(npy::MAGIC) {
            Self::from_npy_bytes(name, bytes)
        } else if let Some(start) = text_start(bytes) {
            Err(RecordingError::Text { name, start })
        } else {
            Err(RecordingError::NotNpy {
                name,
                detail: "it starts with neither the .npy magic \\x93NUMPY nor the .npz \
                         (zip) magic PK"
                    .into(),
            })
        }
    }

    /// Parses and validates the bytes of a `.npy` file; `name` is used in errors.
    pub(crate) fn from_npy_bytes(
        name: impl Into<String>,
        bytes: &[u8],
    ) -> Result<Self, RecordingError> {
        let name = name.into();
        let header = npy::parse_header(&name, bytes)?;
        let body = bytes.get(header.data_start..).unwrap_or_default();
        let data = npy::pressure(&name, &header, body)?;
        Self::validated(name, data, None, None)
    }

    /// Parses and validates the bytes of a numpy `.npz` archive; `name` is used in errors.
    pub(crate) fn from_npz_bytes(
        name: impl Into<String>,
        bytes: &[u8],
    ) -> Result<Self, RecordingError> {
        let name = name.into();
        let npz = npz::read(&name, bytes)?;
        Self::validated(name, npz.pressure, npz.rate_hz, npz.pitch_mm)
    }

    /// Validates an in-memory `[T, rows, cols]` array (tests, other front ends).
    pub fn from_array(
        name: impl Into<String>,
        data: ArrayView3<f64>,
    ) -> Result<Self, RecordingError> {
        // Fortran-order files arrive as a transposed view; store C order so every later
        // stage can walk frames as contiguous rows.
        Self::validated(
            name.into(),
            data.as_standard_layout().into_owned(),
            None,
            None,
        )
    }

    fn validated(
        name: String,
        data: Array3<f64>,
        rate_hz: Option<f64>,
        pitch_mm: Option<f64>,
    ) -> Result<Self, RecordingError> {
        let (t, r, c) = data.dim();
        if t == 0 || r == 0 || c == 0 {
            return Err(RecordingError::Empty {
                name,
                shape: [t, r, c],
            });
        }
        // The indexed search only where there is something to find (it is several
        // times slower than the plain pass over a long recording).
        let infinite = data.iter().any(|v| v.is_infinite());
        if let Some(((frame, row, col), _)) = infinite
            .then(|| data.indexed_iter().find(|(_, v)| v.is_infinite()))
            .flatten()
        {
            return Err(RecordingError::Infinite {
                name,
                frame,
                row,
                col,
            });
        }
        if data.iter().all(|v| v.is_nan()) {
            return Err(RecordingError::AllNan { name });
        }
        for (field, value, range, unit) in [
            ("rate_hz", rate_hz, RATE_HZ_RANGE, "Hz"),
            ("pitch_mm", pitch_mm, PITCH_MM_RANGE, "mm"),
        ] {
            if let Some(value) = value.filter(|v| !range.contains(v)) {
                return Err(RecordingError::MetadataRange {
                    name,
                    field,
                    value,
                    range,
                    unit,
                });
            }
        }
        let data = if data.is_standard_layout() {
            data
        } else {
            data.as_standard_layout().into_owned()
        };
        Ok(Self {
            name,
            data,
            rate_hz,
            pitch_mm,
        })
    }

    /// The rate and pitch the file declares, for [`Metadata::resolve`](touchc_model::config::Metadata::resolve).
    pub fn file_metadata(&self) -> FileMetadata {
        FileMetadata {
            rate_hz: self.rate_hz,
            pitch_mm: self.pitch_mm,
        }
    }

    /// The frame rate the file declares (`rate_hz` in a `.npz`), validated against
    /// [`RATE_HZ_RANGE`]; `None` for a `.npy` or an archive without it.
    pub fn file_rate_hz(&self) -> Option<f64> {
        self.rate_hz
    }

    /// The cell pitch the file declares (`pitch_mm` in a `.npz`), validated against
    /// [`PITCH_MM_RANGE`]; `None` for a `.npy` or an archive without it.
    pub fn file_pitch_mm(&self) -> Option<f64> {
        self.pitch_mm
    }

    /// The file name (or in-memory name) used in messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The raw psi values, `[T, rows, cols]`, NaN outside the sleeve.
    pub fn data(&self) -> ArrayView3<'_, f64> {
        self.data.view()
    }

    /// Shape `(frames, rows, cols)`.
    pub fn dim(&self) -> (usize, usize, usize) {
        self.data.dim()
    }
}

/// The first line of `bytes` (at most 40 characters) when they start as text: printable
/// characters and whitespace up to the first line break, or through the first dozen
/// bytes.
fn text_start(bytes: &[u8]) -> Option<String> {
    let head = &bytes[..bytes.len().min(64)];
    let line = head.split(|&b| b == b'\n').next().unwrap_or_default();
    let text = std::str::from_utf8(line).ok()?;
    let printable = |c: char| !c.is_control() || c == '\t' || c == '\r';
    if text.is_empty() || !text.chars().all(printable) {
        return None;
    }
    Some(text.trim_end().chars().take(40).collect())
}
