//! The contacts of a synthetic recording: how each gesture moves and presses, frame by
//! frame, with the sensor's flicker.

use super::{Gesture, Sensor, SynthSpec, COLS, ROWS};

/// Pause between gestures, seconds (10 frames at the sleeve's 20 Hz).
pub(super) const PAUSE_S: f64 = 0.5;
/// Amplitude factor of a flickering frame: a 1 psi contact reads 0.03 psi.
pub(super) const FLICKER_FACTOR: f64 = 0.03;
/// Shortest and longest dropout of a flickering contact, seconds.
pub(super) const FLICKER_S: (f64, f64) = (0.019, 0.037);
/// Least time between two dropouts of one contact, seconds.
pub(super) const FLICKER_SPACING_S: f64 = 0.1;
/// Sweeps per second of `rub` (back and forth is one).
pub(super) const RUB_HZ: f64 = 1.5;
/// A contact's radius is where it falls to this share of its peak.
pub(super) const RADIUS_LEVEL: f64 = 0.1;

/// How a contact's pressure falls off from its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Profile {
    /// `exp(-d^2 / 2)` in units of the blob's sigmas: a fingertip, a heel.
    Gaussian,
    /// `exp(-d^4 / 2)`: flat on top, falling fast at the rim (a flat hand).
    Flat,
}

/// One contact: where it is and how hard it presses at a given time.
pub(super) struct Contact {
    pub(super) gesture: Gesture,
    pub(super) start: f64,
    pub(super) length: f64,
    pub(super) peak_psi: f64,
    /// Blob size along the arm and across it, in cells.
    pub(super) sigma: (f64, f64),
    pub(super) profile: Profile,
    /// Rise and fall time, seconds; `None` rises and falls over the whole contact
    /// (the shipped examples).
    pub(super) ramp_s: Option<f64>,
    /// Centre (col, row) at relative time `u` in [0, 1], cell edges at integers.
    pub(super) path: Box<dyn Fn(f64) -> (f64, f64)>,
    /// A broad, weaker region beside the peak that moves with it (the heel of a flat
    /// hand); part of the same contact.
    pub(super) lobe: Option<Lobe>,
    /// Pressure that wavers while pressing: `(depth, hz)` dips the pressure to
    /// `1 - depth` of the envelope `hz` times a second (a light stroke whose pressure
    /// comes and goes).
    pub(super) waver: Option<(f64, f64)>,
}

/// A Gaussian region of a contact, offset from its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Lobe {
    /// Offset from the contact's centre (along the arm, across it), cells.
    pub(super) offset: (f64, f64),
    /// Size along the arm and across it, cells.
    pub(super) sigma: (f64, f64),
    /// Its peak as a share of the contact's peak.
    pub(super) share: f64,
}

impl Contact {
    /// The share of the peak pressed at time `t` (0 outside the contact).
    pub(super) fn envelope(&self, t: f64) -> f64 {
        let u = (t - self.start) / self.length;
        if !(0.0..=1.0).contains(&u) {
            return 0.0;
        }
        let half_pi = std::f64::consts::FRAC_PI_2;
        match self.ramp_s {
            // A raised-cosine envelope: no step at touch-down or lift-off.
            None => (std::f64::consts::PI * u).sin().powi(2),
            Some(ramp) => {
                let edge = (t - self.start).min(self.start + self.length - t);
                if edge >= ramp {
                    1.0
                } else {
                    (half_pi * edge / ramp).sin().powi(2)
                }
            }
        }
    }

    /// The share of the peak pressed at time `t`, with the contact's wavering.
    pub(super) fn level(&self, t: f64) -> f64 {
        let envelope = self.envelope(t);
        match self.waver {
            Some((depth, hz)) => {
                let phase = std::f64::consts::TAU * hz * (t - self.start);
                envelope * (1.0 - depth * 0.5 * (1.0 - phase.cos()))
            }
            None => envelope,
        }
    }

    /// Centre (col, row) at time `t`, cell edges at integers.
    pub(super) fn centre(&self, t: f64) -> (f64, f64) {
        (self.path)(((t - self.start) / self.length).clamp(0.0, 1.0))
    }

    pub(super) fn pressure(&self, t: f64, r: usize, c: usize) -> f64 {
        let envelope = self.level(t);
        if envelope == 0.0 {
            return 0.0;
        }
        let u = (t - self.start) / self.length;
        let (x, y) = (self.path)(u);
        let dx = (c as f64 + 0.5 - x) / self.sigma.0;
        let dy = (r as f64 + 0.5 - y) / self.sigma.1;
        let d2 = dx * dx + dy * dy;
        let fall = match self.profile {
            Profile::Gaussian => (-0.5 * d2).exp(),
            Profile::Flat => (-0.5 * d2 * d2).exp(),
        };
        let lobe = self.lobe.map_or(0.0, |l| {
            let dx = (c as f64 + 0.5 - x - l.offset.0) / l.sigma.0;
            let dy = (r as f64 + 0.5 - y - l.offset.1) / l.sigma.1;
            l.share * (-0.5 * (dx * dx + dy * dy)).exp()
        });
        self.peak_psi * envelope * (fall + lobe)
    }

    /// Distance from the centre, in cells along the longer axis, where the pressure
    /// falls to [`RADIUS_LEVEL`] of the peak.
    pub(super) fn radius_cells(&self) -> f64 {
        let d2 = 2.0 * (1.0 / RADIUS_LEVEL).ln();
        let d = match self.profile {
            Profile::Gaussian => d2.sqrt(),
            Profile::Flat => d2.sqrt().sqrt(),
        };
        let own = d * self.sigma.0.max(self.sigma.1);
        // A lobe reaches a tenth of the contact's peak where its own fall reaches
        // `RADIUS_LEVEL / share`.
        self.lobe.map_or(own, |l| {
            let level = (RADIUS_LEVEL / l.share).min(1.0);
            let reach = (2.0 * (1.0 / level).ln()).sqrt() * l.sigma.0.max(l.sigma.1);
            own.max(l.offset.0.hypot(l.offset.1) + reach)
        })
    }
}

/// SplitMix64: a small, well-mixed generator, so recordings are reproducible
/// everywhere without a dependency.
pub(super) struct Rng(pub(super) u64);

impl Rng {
    pub(super) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub(super) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub(super) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal, by Box-Muller.
    pub(super) fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Where gestures happen: the shipped gestures are laid out on the sleeve's 21 x 8
/// cells; another frame scales their positions (not their sizes) to its own.
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    /// Scale of positions along the arm and across it.
    pub(super) sx: f64,
    pub(super) sy: f64,
    pub(super) rate_hz: f64,
    pub(super) pitch_mm: f64,
    pub(super) cols: f64,
    pub(super) rows: f64,
}

impl Frame {
    pub(super) fn of(sensor: Sensor, rate_hz: f64) -> Frame {
        Frame {
            sx: sensor.cols() as f64 / COLS as f64,
            sy: sensor.rows() as f64 / ROWS as f64,
            rate_hz,
            pitch_mm: sensor.pitch_mm(),
            cols: sensor.cols() as f64,
            rows: sensor.rows() as f64,
        }
    }

    /// Seconds to travel `cells` at `mps`.
    pub(super) fn travel_s(&self, cells: f64, mps: f64) -> f64 {
        cells.abs() * self.pitch_mm / 1000.0 / mps
    }
}

/// Per contact and frame: true where the contact flickers (reads almost nothing).
///
/// Dropouts arrive at `spec.flicker` per second while the contact presses fully, last
/// [`FLICKER_S`] (one or two frames at 54 Hz, as measured on real captures) and are at
/// least [`FLICKER_SPACING_S`] apart; a frame flickers when its time falls inside one.
/// So a 20 Hz recording of the same touch sees fewer, single-frame dropouts.
pub(super) fn flicker_frames(
    contacts: &[Contact],
    frames: usize,
    rate: f64,
    spec: &SynthSpec,
) -> Vec<Vec<bool>> {
    let mut dim = vec![vec![false; frames]; contacts.len()];
    if spec.flicker.is_nan() || spec.flicker <= 0.0 {
        return dim;
    }
    let mut rng = Rng(spec.seed ^ 0xF11C_4E42_D0D0_5EED);
    for (k, c) in contacts.iter().enumerate() {
        let full = |t: f64| c.envelope(t) >= 0.999;
        let mut t = c.start;
        loop {
            t += -(1.0 - rng.uniform()).ln() / spec.flicker;
            let d = rng.range(FLICKER_S.0, FLICKER_S.1);
            if t + d + FLICKER_SPACING_S / 2.0 > c.start + c.length {
                break;
            }
            // Only while pressing fully, with full pressure on both sides.
            if full(t - 1.0 / rate) && full(t + d + 1.0 / rate) {
                let first = (t * rate).ceil() as usize;
                let last = ((t + d) * rate).floor() as usize;
                let last = last.min(frames.saturating_sub(1));
                if first <= last {
                    dim[k][first..=last].fill(true);
                }
            }
            t += d + FLICKER_SPACING_S;
        }
    }
    dim
}
