//! Synthetic recordings: seeded, physically plausible touches on a sensor, so anyone can
//! run the whole chain without a pressure sleeve, and with the truth of where each
//! contact was, so tests can measure what tracking keeps and loses.
//!
//! A recording is `[T, rows, cols]` psi at the sensor's rate: `quiet` frames of sensor
//! noise, the gestures one after another with a short pause between, then `quiet` frames
//! again. Each contact is a pressure blob (anisotropic Gaussian, or flat-topped for a
//! palm) whose centre moves along a path and whose amplitude rises and falls smoothly.
//! Cells outside the sleeve mask are NaN, as in the public data set.
//!
//! Two sensors: the paper's 8 x 21 sleeve at 20 Hz and a 10 x 10 grid at 54 Hz, both of
//! one-inch cells (see [`Sensor`]). The gestures' defaults are those of the shipped
//! examples (`examples/generate.sh`: the same spec gives the same bytes as ever);
//! [`Tuning`] sets their speed, duration, frequency and spacing in physical units for the
//! cases real touch holds (fast strokes, brief taps, shakes), and [`SynthSpec`] adds
//! flicker and recordings that begin or end mid-touch. [`generate_with_truth`] also says
//! where every contact was, frame by frame ([`Truth`], `touchc synth --truth`).

#![deny(missing_docs)]

use ndarray::Array3;
use serde::{Deserialize, Serialize};

pub mod cases;
mod contacts;
pub mod fabric;
mod gestures;

pub use fabric::Fabric;

use contacts::{flicker_frames, Contact, Frame, Rng, FLICKER_FACTOR, PAUSE_S};
use gestures::gesture;

/// Rows of the published sensor frame.
pub(crate) const ROWS: usize = touchc_model::geometry::PAPER_GRID.0;
/// Columns of the published sensor frame.
pub(crate) const COLS: usize = touchc_model::geometry::PAPER_GRID.1;

/// A gesture the generator can produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Gesture {
    /// One fingertip-sized contact sliding along the arm over about 1.2 s
    /// ([`Tuning::stroke_speed_mps`] sets its speed).
    Stroke,
    /// Three short fingertip presses at one spot ([`Tuning::tap_s`] sets their length).
    Tap,
    /// Four flat-hand pats at neighbouring spots.
    Pat,
    /// A grip: four fingertips on one side and the heel of the hand on the other, together.
    Squeeze,
    /// A contact moving back and forth across the arm at 3 Hz
    /// ([`Tuning::shake_hz`], [`Tuning::shake_amplitude_mm`]).
    Shake,
    /// A flat hand pressed and held: one large, flat-topped contact for 1.5 s.
    Palm,
    /// Three strokes back and forth along the arm, each lifted [`Tuning::gap_s`]
    /// (150 ms by default) before the next touches down where it ended
    /// ([`Tuning::strokes`] sets how many, [`Tuning::gap_max_s`] varies the gaps).
    Strokes,
    /// A flat hand held for 3 s ([`Tuning::hold_s`]): a flat-topped strong region with a
    /// broad heel about a third as strong beside it, towards the wrist.
    Hand,
    /// A flat hand rubbing back and forth along the arm at 1.5 Hz for 3 s, its speed
    /// peaking at [`Tuning::stroke_speed_mps`] (0.45 m/s by default) mid-sweep.
    Rub,
    /// Two seconds of nothing but sensor noise.
    Rest,
    /// A light fingertip wandering to and fro over a few cells for 3 s, its pressure
    /// coming and going.
    Tickle,
    /// Fingernails scratching back and forth along the arm at 4 Hz for 3 s: a narrow
    /// contact across the arm, up to 1.6 m/s mid-sweep.
    Scratch,
}

impl Gesture {
    /// The gesture's name on the command line and in truth files.
    pub fn name(self) -> &'static str {
        match self {
            Gesture::Stroke => "stroke",
            Gesture::Tap => "tap",
            Gesture::Pat => "pat",
            Gesture::Squeeze => "squeeze",
            Gesture::Shake => "shake",
            Gesture::Palm => "palm",
            Gesture::Strokes => "strokes",
            Gesture::Hand => "hand",
            Gesture::Rub => "rub",
            Gesture::Rest => "rest",
            Gesture::Tickle => "tickle",
            Gesture::Scratch => "scratch",
        }
    }
}

/// Which sleeve outline to mask the frame with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Mask {
    /// The 142-cell sleeve of the reference recordings.
    Cells142,
    /// A smaller 120-cell sleeve.
    Cells120,
}

impl Mask {
    /// Cells per row that carry a sensor (the rest of the row is NaN).
    fn row_widths(self) -> [usize; ROWS] {
        match self {
            Mask::Cells142 => [11, 18, 21, 21, 21, 21, 18, 11],
            Mask::Cells120 => [6, 12, 21, 21, 21, 21, 12, 6],
        }
    }

    /// True when cell `(r, c)` carries a sensor.
    pub(crate) fn has_cell(self, r: usize, c: usize) -> bool {
        c < self.row_widths()[r]
    }
}

/// The sensor a recording imitates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Sensor {
    /// The paper's sleeve: 8 x 21 one-inch cells (outline from [`Mask`]) at 20 Hz.
    Sleeve,
    /// A 10 x 10 fabric grid of about one-inch cells at 54 Hz, every cell live (the
    /// other lab's sensor of `REAL-TOUCH`-style recordings).
    Grid10,
}

impl Sensor {
    /// Rows of the frame.
    pub fn rows(self) -> usize {
        match self {
            Sensor::Sleeve => ROWS,
            Sensor::Grid10 => 10,
        }
    }

    /// Columns of the frame.
    pub fn cols(self) -> usize {
        match self {
            Sensor::Sleeve => COLS,
            Sensor::Grid10 => 10,
        }
    }

    /// Frame rate, Hz.
    pub fn rate_hz(self) -> f64 {
        match self {
            Sensor::Sleeve => touchc_model::config::Sampling::PAPER.rate_hz,
            Sensor::Grid10 => 54.0,
        }
    }

    /// Cell pitch, mm.
    pub fn pitch_mm(self) -> f64 {
        // Both sensors have the paper's one-inch cells.
        touchc_model::config::Sampling::PAPER.pitch_mm
    }

    /// The sensor's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Sleeve => "sleeve",
            Sensor::Grid10 => "grid10",
        }
    }
}

/// Physical settings of the gestures; `None` keeps a gesture as the shipped examples
/// have it (so their bytes never change).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tuning {
    /// Speed of `stroke` and `strokes` along the arm, m/s (`strokes` default: 0.3).
    pub stroke_speed_mps: Option<f64>,
    /// Length of each `tap`, seconds (default 0.2); a frame falls inside its plateau.
    pub tap_s: Option<f64>,
    /// Frequency of `shake`, Hz (default 3).
    pub shake_hz: Option<f64>,
    /// Amplitude of `shake` across the arm, mm either side (default two cells).
    pub shake_amplitude_mm: Option<f64>,
    /// Time between lift-off and the next touch-down within `strokes`, seconds
    /// (default 0.15).
    pub gap_s: Option<f64>,
    /// The longest such time: each gap is drawn between `gap_s` and this, and each
    /// stroke changes speed along its way (half to one and a half times its speed) and
    /// presses lightly (0.2-0.4 psi), its pressure dipping by half 2-4 times a second.
    pub gap_max_s: Option<f64>,
    /// Strokes in `strokes` (default 3).
    pub strokes: Option<usize>,
    /// How long `hand` and `rub` press, seconds (default 3).
    pub hold_s: Option<f64>,
}

/// Everything that shapes a synthetic recording.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSpec {
    /// Gestures, played one after another.
    pub gestures: Vec<Gesture>,
    /// Seed of the random generator: the same spec gives the same bytes.
    pub seed: u64,
    /// Sleeve outline (the sleeve sensor only).
    pub mask: Mask,
    /// Standard deviation of the sensor noise, psi.
    pub noise_psi: f64,
    /// Noise-only frames before and after the gestures.
    pub quiet_frames: usize,
    /// The sensor imitated.
    pub sensor: Sensor,
    /// Speeds, durations and spacing of the gestures.
    pub tuning: Tuning,
    /// Dropouts per second while a contact presses fully: it reads almost nothing for
    /// 19-37 ms (one or two frames at 54 Hz; sensor flicker; 0 = none).
    pub flicker: f64,
    /// Start the recording in the middle of the first contact (no quiet frames before).
    pub begin_mid_touch: bool,
    /// End the recording in the middle of the last contact (no quiet frames after).
    pub end_mid_touch: bool,
    /// Sample the touch at this rate instead of the sensor's own, Hz (the same touch at
    /// another rate: the gestures and their random draws do not change).
    pub rate_hz: Option<f64>,
    /// Read the touch as a fabric grid does ([`Fabric`]: uneven, wandering cells that
    /// drop out now and then); `None`: smooth blobs, as the shipped examples.
    pub fabric: Option<Fabric>,
}

impl Default for SynthSpec {
    fn default() -> Self {
        SynthSpec {
            gestures: vec![Gesture::Stroke],
            seed: 1,
            mask: Mask::Cells142,
            noise_psi: 0.004,
            quiet_frames: 30,
            sensor: Sensor::Sleeve,
            tuning: Tuning::default(),
            flicker: 0.0,
            begin_mid_touch: false,
            end_mid_touch: false,
            rate_hz: None,
            fabric: None,
        }
    }
}

impl SynthSpec {
    /// Cell `(r, c)` carries a sensor.
    fn has_cell(&self, r: usize, c: usize) -> bool {
        match self.sensor {
            Sensor::Sleeve => self.mask.has_cell(r, c),
            Sensor::Grid10 => true,
        }
    }

    /// The rate the recording is sampled at, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz.unwrap_or(self.sensor.rate_hz())
    }
}

/// Where one contact was in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TruthPoint {
    /// Frame index in the recording (before any tare or trim).
    pub frame: usize,
    /// Time of the frame, seconds from the first frame.
    pub t_s: f64,
    /// Centre row, in cells (cell `r` has its centre at `r`, as in `coverage`).
    pub row: f64,
    /// Centre column, in cells.
    pub col: f64,
    /// Centre along the arm, mm from the frame's edge (cell `c` spans `[c, c+1)` pitches).
    pub x_mm: f64,
    /// Centre across the arm, mm.
    pub y_mm: f64,
    /// Where the contact falls to a tenth of its peak, cells (its longer axis).
    pub radius_cells: f64,
    /// The same, mm.
    pub radius_mm: f64,
    /// Peak pressure of the contact in this frame, psi (0 between touch-down and lift-off
    /// only where it flickers to almost nothing).
    pub pressure_psi: f64,
}

/// One true contact, frame by frame, over the frames it presses at all.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthContact {
    /// Number of the contact, in order of touch-down within its gesture list.
    pub id: usize,
    /// The gesture it belongs to.
    pub gesture: Gesture,
    /// Its frames, in order.
    pub points: Vec<TruthPoint>,
}

/// Where every contact of a synthetic recording really was (`touchc synth --truth`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// The sensor imitated.
    pub sensor: Sensor,
    /// Frame rate, Hz.
    pub rate_hz: f64,
    /// Cell pitch, mm.
    pub pitch_mm: f64,
    /// Frames in the recording.
    pub frames: usize,
    /// Rows of a frame.
    pub rows: usize,
    /// Columns of a frame.
    pub cols: usize,
    /// The contacts.
    pub contacts: Vec<TruthContact>,
}

/// Generates a recording, `[T, rows, cols]` psi, NaN outside the mask.
pub fn generate(spec: &SynthSpec) -> Array3<f64> {
    generate_with_truth(spec).0
}

/// Generates a recording and says where each contact was.
pub fn generate_with_truth(spec: &SynthSpec) -> (Array3<f64>, Truth) {
    let sensor = spec.sensor;
    let fr = Frame::of(sensor, spec.rate_hz());
    let rate = fr.rate_hz;
    let mut rng = Rng(spec.seed);
    let mut contacts = Vec::new();
    let mut t = spec.quiet_frames as f64 / rate;
    for (i, &g) in spec.gestures.iter().enumerate() {
        if i > 0 {
            t += PAUSE_S;
        }
        let (mut cs, length) = gesture(g, t, &mut rng, &spec.tuning, fr);
        contacts.append(&mut cs);
        t += length;
    }
    let frames = (t * rate).ceil() as usize + spec.quiet_frames;
    let (rows, cols) = (sensor.rows(), sensor.cols());
    // Flicker draws from its own stream, so a spec without it keeps its bytes.
    let dim = flicker_frames(&contacts, frames, rate, spec);
    let amplitude = |k: usize, f: usize| if dim[k][f] { FLICKER_FACTOR } else { 1.0 };
    let touch_at = |f: usize, r: usize, c: usize| -> f64 {
        let t = f as f64 / rate;
        contacts
            .iter()
            .enumerate()
            .map(|(k, contact)| contact.pressure(t, r, c) * amplitude(k, f))
            .sum()
    };
    // The fabric reads the touch before the noise, from its own stream, so the noise
    // draws (and a spec without a fabric, byte for byte) do not change.
    let fabric_touch = spec.fabric.map(|fabric| {
        let mut touch = Array3::from_shape_fn((frames, rows, cols), |(f, r, c)| touch_at(f, r, c));
        fabric.apply(&mut touch, rate, spec.seed);
        touch
    });
    let mut data = Array3::from_shape_fn((frames, rows, cols), |(f, r, c)| {
        if !spec.has_cell(r, c) {
            return f64::NAN;
        }
        let touch = match &fabric_touch {
            Some(t) => t[[f, r, c]],
            None => touch_at(f, r, c),
        };
        touch + spec.noise_psi * rng.normal()
    });
    let mid = |c: &Contact| ((c.start + c.length / 2.0) * rate).round() as usize;
    let first = match (spec.begin_mid_touch, contacts.first()) {
        (true, Some(c)) => mid(c).min(frames.saturating_sub(1)),
        _ => 0,
    };
    let end = match (spec.end_mid_touch, contacts.last()) {
        (true, Some(c)) => (mid(c) + 1).clamp(first + 1, frames),
        _ => frames,
    };
    if first > 0 || end < frames {
        data = data.slice(ndarray::s![first..end, .., ..]).to_owned();
    }
    let truth = Truth {
        sensor,
        rate_hz: rate,
        pitch_mm: fr.pitch_mm,
        frames: end - first,
        rows,
        cols,
        contacts: contacts
            .iter()
            .enumerate()
            .map(|(id, c)| TruthContact {
                id,
                gesture: c.gesture,
                points: (first..end)
                    .filter_map(|f| {
                        let t = f as f64 / rate;
                        let pressure = c.peak_psi * c.level(t) * amplitude(id, f);
                        let inside = t >= c.start && t <= c.start + c.length;
                        inside.then(|| {
                            let (x, y) = c.centre(t);
                            let radius = c.radius_cells();
                            TruthPoint {
                                frame: f - first,
                                t_s: (f - first) as f64 / rate,
                                row: y - 0.5,
                                col: x - 0.5,
                                x_mm: x * fr.pitch_mm,
                                y_mm: y * fr.pitch_mm,
                                radius_cells: radius,
                                radius_mm: radius * fr.pitch_mm,
                                pressure_psi: pressure,
                            }
                        })
                    })
                    .collect(),
            })
            .filter(|c| !c.points.is_empty())
            .collect(),
    };
    (data, truth)
}

/// Encodes a recording as `.npy` bytes (little-endian f64, C order).
pub fn to_npy(recording: &Array3<f64>) -> Result<Vec<u8>, ndarray_npy::WriteNpyError> {
    use ndarray_npy::WriteNpyExt;
    let mut bytes = Vec::new();
    recording.write_npy(&mut bytes)?;
    Ok(bytes)
}

/// Why a recording could not be encoded as a `.npz` archive.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NpzWriteError {
    /// An array could not be encoded as `.npy`.
    #[error("cannot encode {member} as .npy")]
    Npy {
        /// The archive member.
        member: &'static str,
        /// What the encoder said.
        #[source]
        source: ndarray_npy::WriteNpyError,
    },
    /// The archive could not be written.
    #[error("cannot write the zip archive")]
    Zip(#[from] zip::result::ZipError),
    /// The archive could not be written.
    #[error("cannot write the zip archive")]
    Io(#[from] std::io::Error),
}

/// The bytes of a numpy `.npz` archive (`np.savez`'s layout: stored members named
/// `<key>.npy`) holding `recording` as `pressure` and the sampling as the scalars
/// `rate_hz` and `pitch_mm`, where `touchc_input::recording::Recording::load` and
/// `np.load` find them: the file compiles at its own rate without `--rate`.
pub fn to_npz(
    recording: &Array3<f64>,
    rate_hz: f64,
    pitch_mm: f64,
) -> Result<Vec<u8>, NpzWriteError> {
    use ndarray_npy::WriteNpyExt;
    use std::io::Write;
    let npy =
        |member: &'static str,
         write: &dyn Fn(&mut Vec<u8>) -> Result<(), ndarray_npy::WriteNpyError>| {
            let mut bytes = Vec::new();
            write(&mut bytes)
                .map(|()| bytes)
                .map_err(|source| NpzWriteError::Npy { member, source })
        };
    let members = [
        (
            "pressure.npy",
            npy("pressure", &|b| recording.write_npy(b))?,
        ),
        (
            "rate_hz.npy",
            npy("rate_hz", &|b| ndarray::arr0(rate_hz).write_npy(b))?,
        ),
        (
            "pitch_mm.npy",
            npy("pitch_mm", &|b| ndarray::arr0(pitch_mm).write_npy(b))?,
        ),
    ];
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    // Stored, as `np.savez`; zip64 only when a member needs it (numpy reads either).
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .large_file(members.iter().any(|(_, b)| b.len() >= u32::MAX as usize));
    for (name, bytes) in &members {
        zip.start_file(*name, options)?;
        zip.write_all(bytes)?;
    }
    Ok(zip.finish()?.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_recording_other_seed_other_noise() {
        let spec = SynthSpec::default();
        let a = to_npy(&generate(&spec)).unwrap();
        assert_eq!(a, to_npy(&generate(&spec)).unwrap());
        let b = to_npy(&generate(&SynthSpec { seed: 2, ..spec })).unwrap();
        assert_ne!(a, b);
    }

    #[test]
    fn mask_counts_and_nan_padding() {
        for (mask, cells) in [(Mask::Cells142, 142), (Mask::Cells120, 120)] {
            let rec = generate(&SynthSpec {
                mask,
                ..SynthSpec::default()
            });
            let frame = rec.index_axis(ndarray::Axis(0), 0);
            assert_eq!(frame.iter().filter(|v| !v.is_nan()).count(), cells);
        }
    }

    #[test]
    fn a_stroke_moves_along_the_arm() {
        let rec = generate(&SynthSpec {
            noise_psi: 0.0,
            ..SynthSpec::default()
        });
        // Column of the strongest cell, frame by frame, while touched.
        let cols: Vec<usize> = rec
            .outer_iter()
            .filter_map(|f| {
                let (i, v) = f
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| !v.is_nan())
                    .max_by(|a, b| a.1.total_cmp(b.1))?;
                (*v > 0.1).then_some(i % COLS)
            })
            .collect();
        assert!(cols.len() >= 10, "{cols:?}");
        assert!(cols.windows(2).all(|w| w[1] >= w[0]), "{cols:?}");
        assert!(cols.last().unwrap() - cols[0] >= 10, "{cols:?}");
        // Quiet frames at both ends.
        assert!(rec
            .index_axis(ndarray::Axis(0), 0)
            .iter()
            .all(|v| v.is_nan() || *v == 0.0));
    }

    #[test]
    fn untuned_gestures_keep_the_shipped_examples_bytes() {
        let cases: [(&[Gesture], u64, Mask, &[u8]); 2] = [
            (
                &[Gesture::Stroke],
                7,
                Mask::Cells142,
                include_bytes!("../../../../examples/stroke.npy"),
            ),
            (
                &[Gesture::Tap, Gesture::Pat],
                11,
                Mask::Cells142,
                include_bytes!("../../../../examples/tap_pat.npy"),
            ),
        ];
        for (gestures, seed, mask, bytes) in cases {
            let spec = SynthSpec {
                gestures: gestures.to_vec(),
                seed,
                mask,
                ..SynthSpec::default()
            };
            assert!(to_npy(&generate(&spec)).unwrap() == bytes, "{gestures:?}");
        }
    }

    fn tuned(sensor: Sensor, gestures: &[Gesture], tuning: Tuning) -> SynthSpec {
        SynthSpec {
            gestures: gestures.to_vec(),
            sensor,
            tuning,
            noise_psi: 0.003,
            quiet_frames: (sensor.rate_hz() * 1.5) as usize,
            ..SynthSpec::default()
        }
    }

    #[test]
    fn a_tuned_stroke_moves_at_its_speed_on_both_sensors() {
        for sensor in [Sensor::Sleeve, Sensor::Grid10] {
            for v in [0.05, 1.5] {
                let spec = tuned(
                    sensor,
                    &[Gesture::Stroke],
                    Tuning {
                        stroke_speed_mps: Some(v),
                        ..Tuning::default()
                    },
                );
                let (rec, truth) = generate_with_truth(&spec);
                assert_eq!(rec.dim().1, sensor.rows());
                assert_eq!(rec.dim().2, sensor.cols());
                assert_eq!(truth.frames, rec.dim().0);
                let pts = &truth.contacts[0].points;
                assert!(pts.len() >= 3, "{sensor:?} {v}: {} frames", pts.len());
                // Speed along the path, from truth positions, mm/s.
                let (a, b) = (pts[0], pts[pts.len() - 1]);
                let dist = ((b.x_mm - a.x_mm).powi(2) + (b.y_mm - a.y_mm).powi(2)).sqrt();
                let speed = dist / (b.t_s - a.t_s) / 1000.0;
                assert!(
                    (speed - v).abs() < 0.25 * v,
                    "{sensor:?}: {speed} m/s for {v}"
                );
                // The recording carries the contact where the truth says.
                let p = pts[pts.len() / 2];
                let (r, c) = (p.row.round() as usize, p.col.round() as usize);
                assert!(rec[[p.frame, r, c]] > 0.5, "{sensor:?} {v}: {p:?}");
            }
        }
    }

    #[test]
    fn a_brief_tap_shows_in_a_frame_even_at_20_hz() {
        let spec = tuned(
            Sensor::Sleeve,
            &[Gesture::Tap],
            Tuning {
                tap_s: Some(0.05),
                ..Tuning::default()
            },
        );
        let (_, truth) = generate_with_truth(&spec);
        assert_eq!(truth.contacts.len(), 3);
        for c in &truth.contacts {
            assert!(c.points.len() <= 2, "{:?}", c.points);
            let peak = c.points.iter().map(|p| p.pressure_psi).fold(0.0, f64::max);
            assert!(peak >= 0.9, "{:?}", c.points);
        }
    }

    #[test]
    fn begin_and_end_mid_touch_cut_the_quiet_frames() {
        let spec = SynthSpec {
            begin_mid_touch: true,
            end_mid_touch: true,
            ..tuned(Sensor::Grid10, &[Gesture::Palm], Tuning::default())
        };
        let (rec, truth) = generate_with_truth(&spec);
        let touched = |f: usize| rec.index_axis(ndarray::Axis(0), f).iter().any(|&v| v > 0.3);
        assert!(touched(0) && touched(rec.dim().0 - 1));
        assert_eq!(truth.contacts[0].points[0].frame, 0);
        // A palm covers many cells at once.
        let cells = rec
            .index_axis(ndarray::Axis(0), 0)
            .iter()
            .filter(|&&v| v > 0.08)
            .count();
        assert!(cells >= 20, "{cells}");
    }

    #[test]
    fn flicker_drops_a_pressing_contact_for_one_or_two_frames() {
        let spec = SynthSpec {
            flicker: 5.0,
            ..tuned(Sensor::Grid10, &[Gesture::Palm], Tuning::default())
        };
        let (_, truth) = generate_with_truth(&spec);
        let p: Vec<f64> = truth.contacts[0]
            .points
            .iter()
            .map(|p| p.pressure_psi)
            .collect();
        // Within the plateau (the ramps at both ends rise and fall through 0.08 psi).
        let full = |i: &usize| p[*i] > 0.3;
        let (a, b) = (
            (0..p.len()).find(full).unwrap(),
            (0..p.len()).rfind(full).unwrap(),
        );
        let low: Vec<usize> = (a..b).filter(|&i| p[i] < 0.08).collect();
        assert!(!low.is_empty(), "{p:?}");
        for i in low {
            // Each dropout is bounded by full pressure within two frames on each side.
            assert!(p[i.saturating_sub(2)..i].iter().any(|&v| v > 0.3), "{p:?}");
            assert!(
                p[i + 1..(i + 3).min(p.len())].iter().any(|&v| v > 0.3),
                "{p:?}"
            );
        }
    }

    #[test]
    fn a_hand_presses_a_weaker_heel_beside_its_flat_top() {
        for sensor in [Sensor::Sleeve, Sensor::Grid10] {
            let spec = SynthSpec {
                noise_psi: 0.0,
                ..cases::spec(sensor, 20.0, &[Gesture::Hand], Tuning::default())
            };
            let (rec, truth) = generate_with_truth(&spec);
            let p = truth.contacts[0].points[truth.contacts[0].points.len() / 2];
            let frame = rec.index_axis(ndarray::Axis(0), p.frame);
            let peak = frame.iter().fold(0.0f64, |m, &v| m.max(v));
            // Cells three cells or more towards the wrist, yet above a fifth of the
            // peak: the heel, a broad region of its own, weaker than the top.
            let heel: Vec<f64> = frame
                .indexed_iter()
                .filter(|((_, c), _)| (*c as f64) <= p.col - 3.0)
                .map(|(_, &v)| v)
                .filter(|&v| v > 0.2 * peak)
                .collect();
            assert!(heel.len() >= 3, "{sensor:?}: {heel:?}");
            assert!(heel.iter().all(|&v| v < 0.5 * peak), "{sensor:?}: {heel:?}");
            assert!(p.radius_cells > 4.0, "{p:?}");
        }
    }

    #[test]
    fn a_rub_goes_back_and_forth_at_its_speed() {
        for v in [0.3, 0.6] {
            let t = Tuning {
                stroke_speed_mps: Some(v),
                ..Tuning::default()
            };
            let (_, truth) =
                generate_with_truth(&cases::spec(Sensor::Grid10, 54.0, &[Gesture::Rub], t));
            let pts = &truth.contacts[0].points;
            let speeds: Vec<f64> = pts
                .windows(2)
                .map(|w| (w[1].x_mm - w[0].x_mm).abs() / (w[1].t_s - w[0].t_s) / 1000.0)
                .collect();
            let top = speeds.iter().fold(0.0f64, |m, &s| m.max(s));
            assert!((top - v).abs() < 0.05 * v, "{v}: {top}");
            // Back and forth: the direction turns at least six times in 3 s.
            let turns = pts
                .windows(3)
                .filter(|w| (w[1].x_mm - w[0].x_mm) * (w[2].x_mm - w[1].x_mm) < 0.0)
                .count();
            assert!(turns >= 6, "{v}: {turns}");
        }
    }

    #[test]
    fn fifteen_strokes_with_varied_gaps() {
        let case = cases::cases_on(Sensor::Sleeve, 54.0)
            .into_iter()
            .find(|c| c.name.starts_with("15 strokes"))
            .unwrap();
        let (_, truth) = generate_with_truth(&case.spec);
        assert_eq!(truth.contacts.len(), 15);
        let gaps: Vec<f64> = truth
            .contacts
            .windows(2)
            .map(|w| w[1].points[0].t_s - w[0].points[w[0].points.len() - 1].t_s)
            .collect();
        // Frame times: within a frame of the drawn 150-400 ms.
        let frame = 1.0 / 54.0;
        assert!(
            gaps.iter()
                .all(|&g| g > 0.15 - frame && g < 0.4 + 2.0 * frame),
            "{gaps:?}"
        );
        assert!(
            gaps.iter().any(|&g| g > 0.3) && gaps.iter().any(|&g| g < 0.25),
            "{gaps:?}"
        );
        // Each stroke keeps its direction.
        for c in &truth.contacts {
            let dir: Vec<f64> = c.points.windows(2).map(|w| w[1].x_mm - w[0].x_mm).collect();
            assert!(dir.iter().all(|d| d * dir[0] > 0.0), "{dir:?}");
        }
    }

    #[test]
    fn another_rate_samples_the_same_touch() {
        let spec = |rate| SynthSpec {
            noise_psi: 0.0,
            ..cases::spec(Sensor::Grid10, rate, &[Gesture::Rub], Tuning::default())
        };
        let (_, a) = generate_with_truth(&spec(20.0));
        let (_, b) = generate_with_truth(&spec(54.0));
        assert_eq!((a.rate_hz, b.rate_hz), (20.0, 54.0));
        // 1 s = 20 frames = 54 frames past the 1.5 s of quiet: the same place.
        let at = |t: &Truth, s: f64| {
            *t.contacts[0]
                .points
                .iter()
                .find(|p| (p.t_s - s).abs() < 1e-9)
                .unwrap()
        };
        let (p, q) = (at(&a, 2.5), at(&b, 2.5));
        assert!((p.x_mm - q.x_mm).abs() < 1e-9 && (p.y_mm - q.y_mm).abs() < 1e-9);
        assert!((p.pressure_psi - q.pressure_psi).abs() < 1e-12);
    }
}
