//! Stage 0: load a pressure-sleeve recording and tare it.
//!
//! A recording is a `.npy` array `[T, rows, cols]` of psi at the sensor frame rate, with
//! NaN for "no sensor cell" (the public data set pads every frame to 8 x 21 cells).
//! Everything a user can get wrong about the file is a typed [`RecordingError`] that
//! names the file, so the CLI can print one clear line.

use std::path::Path;

use ndarray::{Array2, Array3, ArrayD, ArrayView3, Axis, Ix3};
use ndarray_npy::{ReadNpyError, ReadNpyExt};

use crate::config::{Baseline, InputConfig, Sampling};

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
    /// The array holds something other than float32 or float64.
    #[error("{name}: unsupported element type {descr}; expected float32 or float64")]
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
         trim at each end need at least {min} frames (input.tare_s, input.trim_s)"
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

/// A validated recording: raw psi, NaN where there is no sensor cell.
///
/// Stored as f64 whatever the file held, because the global statistics downstream are
/// accumulated in f64 and an f32 file converts exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    name: String,
    data: Array3<f64>,
}

impl Recording {
    /// Loads and validates a `.npy` file (float32 or float64, C or Fortran order).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, RecordingError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
            name: name.clone(),
            source,
        })?;
        Self::from_npy_bytes(name, &bytes)
    }

    /// Parses and validates the bytes of a `.npy` file; `name` is used in errors.
    pub fn from_npy_bytes(name: impl Into<String>, bytes: &[u8]) -> Result<Self, RecordingError> {
        let name = name.into();
        // ndarray-npy does not convert element types, so try f64 first and fall back to
        // f32 only when the header names another type.
        let data: ArrayD<f64> = match ArrayD::<f64>::read_npy(bytes) {
            Ok(a) => a,
            Err(ReadNpyError::WrongDescriptor(_)) => match ArrayD::<f32>::read_npy(bytes) {
                Ok(a) => a.mapv(f64::from),
                Err(e) => return Err(npy_error(name, e)),
            },
            Err(e) => return Err(npy_error(name, e)),
        };
        let ndim = data.ndim();
        let data = data
            .into_dimensionality::<Ix3>()
            .map_err(|_| RecordingError::WrongRank {
                name: name.clone(),
                ndim,
            })?;
        Self::from_array(name, data.view())
    }

    /// Validates an in-memory `[T, rows, cols]` array (tests, other front ends).
    pub fn from_array(
        name: impl Into<String>,
        data: ArrayView3<f64>,
    ) -> Result<Self, RecordingError> {
        let name = name.into();
        let (t, r, c) = data.dim();
        if t == 0 || r == 0 || c == 0 {
            return Err(RecordingError::Empty {
                name,
                shape: [t, r, c],
            });
        }
        if let Some(((frame, row, col), _)) = data.indexed_iter().find(|(_, v)| v.is_infinite()) {
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
        // Fortran-order files arrive as a transposed view; store C order so every later
        // stage can walk frames as contiguous rows.
        Ok(Self {
            name,
            data: data.as_standard_layout().into_owned(),
        })
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

    /// Tare and trim: subtract each cell's baseline, drop `trim_s` at both ends, and turn
    /// NaN into 0. `sampling` turns the config's seconds into frames.
    ///
    /// The `leading` baseline (the paper) is each cell's mean over the first `tare_s`,
    /// with numpy semantics: a cell that is NaN in any tare frame has a NaN mean and is
    /// therefore 0 ("no cell") for the whole recording; a NaN reading elsewhere is 0 in
    /// that frame only. The `robust` baseline is each cell's `baseline_quantile` over
    /// the whole recording (NaN readings ignored; a cell with none is 0), so a recording
    /// may begin or end mid-touch.
    pub fn tare(
        &self,
        cfg: &InputConfig,
        sampling: &Sampling,
    ) -> Result<Array3<f64>, RecordingError> {
        let tare = match cfg.baseline {
            Baseline::Leading => sampling.frames(cfg.tare_s),
            Baseline::Robust => 0,
        };
        let trim = sampling.frames(cfg.trim_s);
        let (t, _, _) = self.dim();
        let min = trim.saturating_mul(2).saturating_add(1).max(tare);
        if t < min {
            return Err(RecordingError::TooShort {
                name: self.name.clone(),
                frames: t,
                tare,
                min,
            });
        }
        let baseline = match cfg.baseline {
            Baseline::Leading => leading_baseline(self.data.view(), tare),
            Baseline::Robust => robust_baseline(self.data.view(), cfg.baseline_quantile),
        };
        let mut out = self
            .data
            .slice(ndarray::s![trim..t - trim, .., ..])
            .to_owned();
        for mut frame in out.axis_iter_mut(Axis(0)) {
            frame.zip_mut_with(&baseline, |v, &m| {
                let x = *v - m;
                *v = if x.is_nan() { 0.0 } else { x };
            });
        }
        Ok(out)
    }
}

/// The recording's own metadata. Until `.npz` input lands (helper "inputs"), a file
/// states neither rate nor pitch, so the command line or the config decides.
impl Recording {
    /// The frame rate the file states (a `.npz` scalar `rate_hz`), Hz.
    pub fn file_rate_hz(&self) -> Option<f64> {
        None
    }

    /// The cell pitch the file states (a `.npz` scalar `pitch_mm`), mm.
    pub fn file_pitch_mm(&self) -> Option<f64> {
        None
    }
}

/// Each cell's mean over the first `frames` frames (0 when `frames` is 0), summed frame
/// by frame as numpy reduces a non-contiguous axis.
fn leading_baseline(data: ArrayView3<f64>, frames: usize) -> Array2<f64> {
    let (_, r, c) = data.dim();
    let mut baseline = Array2::<f64>::zeros((r, c));
    if frames > 0 {
        for frame in data.axis_iter(Axis(0)).take(frames) {
            baseline += &frame;
        }
        baseline /= frames as f64;
    }
    baseline
}

/// Each cell's `q`-quantile over every frame (linear interpolation between order
/// statistics, numpy's default), NaN readings ignored; NaN for a cell that is never
/// read, which the tare then turns into 0 ("no cell").
fn robust_baseline(data: ArrayView3<f64>, q: f64) -> Array2<f64> {
    let (_, r, c) = data.dim();
    let mut values = Vec::new();
    Array2::from_shape_fn((r, c), |(row, col)| {
        values.clear();
        values.extend(
            data.slice(ndarray::s![.., row, col])
                .iter()
                .copied()
                .filter(|v| !v.is_nan()),
        );
        quantile(&mut values, q)
    })
}

/// The `q`-quantile of `values` (reordered in place); NaN when empty.
fn quantile(values: &mut [f64], q: f64) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    values.sort_unstable_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (n - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    let w = pos - lo as f64;
    values[lo] + w * (values[hi] - values[lo])
}

fn npy_error(name: String, e: ReadNpyError) -> RecordingError {
    match e {
        ReadNpyError::Io(source) => RecordingError::Io { name, source },
        ReadNpyError::WrongDescriptor(descr) => RecordingError::UnsupportedDtype {
            name,
            descr: descr.to_string(),
        },
        other => RecordingError::NotNpy {
            name,
            detail: other.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    #[test]
    fn tare_subtracts_baseline_and_trims() {
        let mut a = Array3::<f64>::zeros((5, 1, 2));
        for t in 0..5 {
            a[[t, 0, 0]] = t as f64;
            a[[t, 0, 1]] = 10.0;
        }
        let rec = Recording::from_array("x", a.view()).unwrap();
        // 2 frames of tare and trim at 20 Hz.
        let cfg = InputConfig {
            tare_s: 0.1,
            trim_s: 0.1,
            ..InputConfig::default()
        };
        let tared = rec.tare(&cfg, &Sampling::PAPER).unwrap();
        assert_eq!(tared.dim(), (1, 1, 2));
        assert_eq!(tared[[0, 0, 0]], 2.0 - 0.5);
        assert_eq!(tared[[0, 0, 1]], 0.0);
    }

    #[test]
    fn too_short_names_minimum() {
        let a = Array3::<f64>::zeros((40, 2, 2));
        let rec = Recording::from_array("short.npy", a.view()).unwrap();
        let err = rec
            .tare(&InputConfig::default(), &Sampling::PAPER)
            .unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("short.npy") && msg.contains("41"), "{msg}");
    }

    /// A recording that starts mid-press: the leading baseline tares the press away,
    /// the robust one keeps it.
    #[test]
    fn robust_baseline_keeps_a_press_at_the_start() {
        let mut a = Array3::<f64>::from_elem((100, 1, 2), 0.3);
        for t in 0..40 {
            a[[t, 0, 0]] = 2.3; // pressed by 2 psi for the first 2 s
        }
        let rec = Recording::from_array("mid-press", a.view()).unwrap();
        let leading = rec.tare(&InputConfig::default(), &Sampling::PAPER).unwrap();
        assert!(
            leading[[0, 0, 0]].abs() < 1e-12,
            "the paper's tare removes the press"
        );
        let robust = InputConfig {
            baseline: Baseline::Robust,
            ..InputConfig::default()
        };
        let tared = rec.tare(&robust, &Sampling::PAPER).unwrap();
        assert_eq!(tared.dim(), (60, 1, 2));
        // Frames 20..40 of the recording are the first 20 after the trim.
        assert!((tared[[0, 0, 0]] - 2.0).abs() < 1e-12);
        assert!((tared[[19, 0, 0]] - 2.0).abs() < 1e-12);
        assert!(tared[[20, 0, 0]].abs() < 1e-12);
        assert!(tared
            .slice(ndarray::s![.., 0, 1])
            .iter()
            .all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn quantile_interpolates_like_numpy() {
        // numpy.quantile([4, 1, 3, 2], 0.1) = 1.3
        assert!((quantile(&mut [4.0, 1.0, 3.0, 2.0], 0.1) - 1.3).abs() < 1e-12);
        assert!(quantile(&mut [], 0.1).is_nan());
    }
}
