//! Synthetic recordings: seeded, physically plausible touches on a sleeve mask, so
//! anyone can run the whole chain without a pressure sleeve.
//!
//! A recording is `[T, 8, 21]` psi at 20 Hz: `quiet` frames of sensor noise, the
//! gestures one after another with a short pause between, then `quiet` frames
//! again. Each contact is an anisotropic Gaussian pressure blob whose centre
//! moves along a path and whose amplitude rises and falls smoothly. Cells outside
//! the sleeve mask are NaN, as in the public data set.

use ndarray::Array3;

/// Rows of the published sensor frame.
pub const ROWS: usize = 8;
/// Columns of the published sensor frame.
pub const COLS: usize = 21;

/// A gesture the generator can produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Gesture {
    /// One fingertip-sized contact sliding along the arm over about 1.2 s.
    Stroke,
    /// Three short fingertip presses at one spot.
    Tap,
    /// Four flat-hand pats at neighbouring spots.
    Pat,
    /// A grip: four fingertips on one side and the heel of the hand on the other, together.
    Squeeze,
    /// A contact moving back and forth across the arm at 3 Hz.
    Shake,
}

/// Which sleeve outline to mask the frame with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
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
    pub fn has_cell(self, r: usize, c: usize) -> bool {
        c < self.row_widths()[r]
    }
}

/// Everything that shapes a synthetic recording.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSpec {
    /// Gestures, played one after another.
    pub gestures: Vec<Gesture>,
    /// Seed of the random generator: the same spec gives the same bytes.
    pub seed: u64,
    /// Sleeve outline.
    pub mask: Mask,
    /// Standard deviation of the sensor noise, psi.
    pub noise_psi: f64,
    /// Noise-only frames before and after the gestures.
    pub quiet_frames: usize,
}

impl Default for SynthSpec {
    fn default() -> Self {
        SynthSpec {
            gestures: vec![Gesture::Stroke],
            seed: 1,
            mask: Mask::Cells142,
            noise_psi: 0.004,
            quiet_frames: 30,
        }
    }
}

const FRAME_RATE_HZ: f64 = 20.0;
const PAUSE_FRAMES: usize = 10;

/// One contact: where it is and how hard it presses at a given time.
struct Contact {
    start: f64,
    length: f64,
    peak_psi: f64,
    /// Blob size along the arm and across it, in cells.
    sigma: (f64, f64),
    /// Centre (col, row) at relative time `u` in [0, 1].
    path: Box<dyn Fn(f64) -> (f64, f64)>,
}

impl Contact {
    fn pressure(&self, t: f64, r: usize, c: usize) -> f64 {
        let u = (t - self.start) / self.length;
        if !(0.0..=1.0).contains(&u) {
            return 0.0;
        }
        // A raised-cosine envelope: no step at touch-down or lift-off.
        let envelope = (std::f64::consts::PI * u).sin().powi(2);
        let (x, y) = (self.path)(u);
        let dx = (c as f64 + 0.5 - x) / self.sigma.0;
        let dy = (r as f64 + 0.5 - y) / self.sigma.1;
        self.peak_psi * envelope * (-0.5 * (dx * dx + dy * dy)).exp()
    }
}

/// SplitMix64: a small, well-mixed generator, so recordings are reproducible
/// everywhere without a dependency.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal, by Box-Muller.
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Contacts of one gesture starting at `t0` seconds; returns them and the gesture length.
fn gesture(kind: Gesture, t0: f64, rng: &mut Rng) -> (Vec<Contact>, f64) {
    let mut contacts = Vec::new();
    let length = match kind {
        Gesture::Stroke => {
            let row = rng.range(2.5, 5.5);
            let (from, to) = (rng.range(1.5, 3.5), rng.range(15.5, 18.0));
            let drift = rng.range(-1.0, 1.0);
            let length = rng.range(1.0, 1.4);
            contacts.push(Contact {
                start: t0,
                length,
                peak_psi: rng.range(1.0, 1.3),
                sigma: (0.9, 0.8),
                path: Box::new(move |u| (from + (to - from) * u, row + drift * u)),
            });
            length
        }
        Gesture::Tap => {
            let (x, y) = (rng.range(4.0, 16.0), rng.range(2.5, 5.5));
            for k in 0..3 {
                contacts.push(Contact {
                    start: t0 + 0.4 * k as f64,
                    length: 0.2,
                    peak_psi: rng.range(0.9, 1.4),
                    sigma: (0.7, 0.7),
                    path: Box::new(move |_| (x, y)),
                });
            }
            1.2
        }
        Gesture::Pat => {
            let mut x = rng.range(3.0, 7.0);
            for k in 0..4 {
                let y = rng.range(3.0, 5.0);
                let here = x;
                contacts.push(Contact {
                    start: t0 + 0.5 * k as f64,
                    length: 0.3,
                    peak_psi: rng.range(0.6, 1.0),
                    sigma: (1.6, 1.4),
                    path: Box::new(move |_| (here, y)),
                });
                x += rng.range(2.5, 4.0);
            }
            2.0
        }
        Gesture::Squeeze => {
            // A grip: four fingertips in a line along one side of the forearm and the
            // heel of the hand on the other, rising, held and released together.
            let x = rng.range(5.0, 9.0);
            let peak = rng.range(0.7, 1.0);
            for k in 0..4 {
                let (fx, fy) = (
                    x + 2.2 * k as f64 + rng.range(-0.3, 0.3),
                    rng.range(1.6, 2.4),
                );
                contacts.push(Contact {
                    start: t0,
                    length: 1.8,
                    peak_psi: peak * rng.range(0.85, 1.0),
                    sigma: (0.8, 0.8),
                    path: Box::new(move |_| (fx, fy)),
                });
            }
            let (px, py) = (x + 3.3, rng.range(5.6, 6.4));
            contacts.push(Contact {
                start: t0,
                length: 1.8,
                peak_psi: peak * 0.8,
                sigma: (2.0, 1.0),
                path: Box::new(move |_| (px, py)),
            });
            1.8
        }
        Gesture::Shake => {
            let x = rng.range(6.0, 15.0);
            contacts.push(Contact {
                start: t0,
                length: 1.5,
                peak_psi: rng.range(0.8, 1.2),
                sigma: (1.0, 1.0),
                path: Box::new(move |u| {
                    (
                        x,
                        4.0 + 2.0 * (2.0 * std::f64::consts::PI * 3.0 * 1.5 * u).sin(),
                    )
                }),
            });
            1.5
        }
    };
    (contacts, length)
}

/// Generates a recording, `[T, 8, 21]` psi, NaN outside the mask.
pub fn generate(spec: &SynthSpec) -> Array3<f64> {
    let mut rng = Rng(spec.seed);
    let mut contacts = Vec::new();
    let mut t = spec.quiet_frames as f64 / FRAME_RATE_HZ;
    for (i, &g) in spec.gestures.iter().enumerate() {
        if i > 0 {
            t += PAUSE_FRAMES as f64 / FRAME_RATE_HZ;
        }
        let (mut cs, length) = gesture(g, t, &mut rng);
        contacts.append(&mut cs);
        t += length;
    }
    let frames = (t * FRAME_RATE_HZ).ceil() as usize + spec.quiet_frames;
    Array3::from_shape_fn((frames, ROWS, COLS), |(f, r, c)| {
        if !spec.mask.has_cell(r, c) {
            return f64::NAN;
        }
        let t = f as f64 / FRAME_RATE_HZ;
        let touch: f64 = contacts.iter().map(|k| k.pressure(t, r, c)).sum();
        touch + spec.noise_psi * rng.normal()
    })
}

/// Encodes a recording as `.npy` bytes (little-endian f64, C order).
pub fn to_npy(recording: &Array3<f64>) -> Result<Vec<u8>, ndarray_npy::WriteNpyError> {
    use ndarray_npy::WriteNpyExt;
    let mut bytes = Vec::new();
    recording.write_npy(&mut bytes)?;
    Ok(bytes)
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
}
