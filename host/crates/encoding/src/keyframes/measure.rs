//! The playback measurement: the protocol crate's player plays an encoding and its
//! output is compared with the signal, on a thread of its own for a long one.

use touch_protocol::player::{code_to_amps, LimitKind};
use touch_protocol::{DeviceConfig, Limits, Player, Status, Stimulus, CHANNELS};

use super::tube;
use super::KeyframeError;

/// Plays `bytes` through the protocol player and compares its output, code by code
/// converted back to amperes, with `signal`; both are 0 A outside their lengths.
/// Returns RMS and max error as fractions of the full scale.
#[cfg(test)]
pub(crate) fn playback_error(
    bytes: &[u8],
    signal: &[[f64; CHANNELS]],
    full_scale_ma: u16,
    limits: Limits,
) -> Result<(f64, f64), KeyframeError> {
    let stim = Stimulus::decode(bytes)?;
    measure(&stim, signal, full_scale_ma, limits, None)
}

/// The playback error on a decoded stimulus. With `bounds = (rms, max)`, gives up as
/// soon as the error is sure to exceed them, and reports `(INFINITY, INFINITY)`.
///
/// A long stimulus (an hour is 3.6 M ticks) is played on a thread of its own while this
/// one sums the error of the ticks already played ([`measure_pipelined`]): the same
/// ticks in the same order, so the same figures, bit for bit, in about the time of the
/// player alone.
pub(super) fn measure(
    stim: &Stimulus<'_>,
    signal: &[[f64; CHANNELS]],
    full_scale_ma: u16,
    limits: Limits,
    bounds: Option<(f64, f64)>,
) -> Result<(f64, f64), KeyframeError> {
    let device = DeviceConfig {
        full_scale_ma,
        limits,
    };
    let ticks = signal.len().max(stim.header().playback_ms() as usize + 1);
    let errors = PlaybackErrors::new(signal, full_scale_ma, bounds, ticks);
    if ticks >= PIPELINE_TICKS && rayon::current_num_threads() > 1 {
        measure_pipelined(stim, &device, errors)
    } else {
        measure_in_turn(stim, &device, errors)
    }
}

/// [`measure`] on this thread: a tick played, then its error.
fn measure_in_turn(
    stim: &Stimulus<'_>,
    device: &DeviceConfig,
    mut errors: PlaybackErrors<'_>,
) -> Result<(f64, f64), KeyframeError> {
    let mut player = Player::new(stim, device);
    loop {
        let tick = player.tick();
        if let Status::Fault(f) = tick.status {
            return Err(limit_hit(f.kind));
        }
        if !errors.add(&tick.codes) {
            return Ok((f64::INFINITY, f64::INFINITY));
        }
        if tick.status == Status::Finished && errors.ticks >= errors.signal.len() {
            return Ok(errors.figures());
        }
    }
}

/// Stimuli of at least this many ticks (a minute) are played on a thread of their own
/// while the error is summed ([`measure_pipelined`]); a shorter one is not worth the
/// thread.
const PIPELINE_TICKS: usize = 60_000;

/// Ticks the player thread hands over at a time.
const PIPELINE_CHUNK: usize = 8_192;

/// What the player thread of [`measure_pipelined`] sends.
enum Played {
    /// The codes of the next ticks, in order.
    Codes(Vec<[u16; CHANNELS]>),
    /// The tick after the last codes sent faulted.
    Fault(LimitKind),
    /// The last codes sent ended the playback.
    End,
}

/// [`measure`] with the player on a scoped thread, its codes passed over in chunks and
/// summed here in tick order. A fault reaches this side after the codes before it, so
/// the bounds are checked on those first, as the one-thread loop does; once the bounds
/// are missed this side stops listening, and the player stops at its next send, which
/// fails.
fn measure_pipelined(
    stim: &Stimulus<'_>,
    device: &DeviceConfig,
    mut errors: PlaybackErrors<'_>,
) -> Result<(f64, f64), KeyframeError> {
    let len = errors.signal.len();
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Played>(4);
        scope.spawn(move || {
            let mut player = Player::new(stim, device);
            let (mut chunk, mut played) = (Vec::with_capacity(PIPELINE_CHUNK), 0usize);
            loop {
                let tick = player.tick();
                if let Status::Fault(f) = tick.status {
                    // A send fails only when the other side has stopped listening.
                    let _ = tx.send(Played::Codes(chunk));
                    let _ = tx.send(Played::Fault(f.kind));
                    return;
                }
                chunk.push(tick.codes);
                played += 1;
                let end = tick.status == Status::Finished && played >= len;
                if end || chunk.len() == PIPELINE_CHUNK {
                    let full = std::mem::replace(&mut chunk, Vec::with_capacity(PIPELINE_CHUNK));
                    if tx.send(Played::Codes(full)).is_err() {
                        return;
                    }
                    if end {
                        let _ = tx.send(Played::End);
                        return;
                    }
                }
            }
        });
        for message in rx {
            match message {
                Played::Codes(codes) => {
                    if !codes.iter().all(|c| errors.add(c)) {
                        // Dropping the receiver on return stops the player.
                        return Ok((f64::INFINITY, f64::INFINITY));
                    }
                }
                Played::Fault(kind) => return Err(limit_hit(kind)),
                Played::End => break,
            }
        }
        Ok(errors.figures())
    })
}

/// The error a limit the player hit is reported as.
fn limit_hit(kind: LimitKind) -> KeyframeError {
    KeyframeError::LimitHit(match kind {
        LimitKind::Peak => "peak",
        LimitKind::Slew => "slew",
        LimitKind::Thermal => "thermal",
    })
}

/// The running error of played codes against the signal (0 A past its end), in tick
/// order, as fractions of the full scale.
struct PlaybackErrors<'s> {
    signal: &'s [[f64; CHANNELS]],
    /// Each 12-bit output code in amperes ([`code_to_amps`], looked up: a division less
    /// per channel and tick).
    amps: Vec<f64>,
    full_scale_ma: u16,
    fs_a: f64,
    /// Sum of squared errors, ticks and channels in order.
    sum2: f64,
    /// Largest error per channel (exact in any order; one running maximum is a chain
    /// through every tick).
    max: [f64; CHANNELS],
    /// Ticks added.
    ticks: usize,
    /// The RMS bound over all `ticks`, as a budget for `sum2`; the max bound.
    sum2_budget: f64,
    max_bound: f64,
}

impl<'s> PlaybackErrors<'s> {
    fn new(
        signal: &'s [[f64; CHANNELS]],
        full_scale_ma: u16,
        bounds: Option<(f64, f64)>,
        ticks: usize,
    ) -> Self {
        let (sum2_budget, max_bound) = match bounds {
            Some((rms, max)) => (rms * rms * (ticks * CHANNELS) as f64, max),
            None => (f64::INFINITY, f64::INFINITY),
        };
        PlaybackErrors {
            signal,
            amps: (0..4096u16)
                .map(|c| code_to_amps(c, full_scale_ma))
                .collect(),
            full_scale_ma,
            fs_a: f64::from(full_scale_ma) / 1000.0,
            sum2: 0.0,
            max: [0.0; CHANNELS],
            ticks: 0,
            sum2_budget,
            max_bound,
        }
    }

    /// Adds one tick's codes; false once the error is sure to miss the bounds.
    #[inline]
    fn add(&mut self, codes: &[u16; CHANNELS]) -> bool {
        let want = self
            .signal
            .get(self.ticks)
            .copied()
            .unwrap_or([0.0; CHANNELS]);
        let mut over = false;
        for (c, &code) in codes.iter().enumerate() {
            let amps = match self.amps.get(usize::from(code)) {
                Some(&a) => a,
                None => code_to_amps(code, self.full_scale_ma),
            };
            let e = ((amps - want[c]) / self.fs_a).abs();
            self.sum2 += e * e;
            self.max[c] = tube::larger(self.max[c], e);
            over |= e > self.max_bound;
        }
        self.ticks += 1;
        !(over || self.sum2 > self.sum2_budget)
    }

    /// RMS and max error over the ticks added.
    fn figures(&self) -> (f64, f64) {
        let max = self.max.iter().fold(0.0, |m, &e| tube::larger(m, e));
        ((self.sum2 / (self.ticks * CHANNELS) as f64).sqrt(), max)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{fields, stroke};
    use super::super::{encode, KeyframeOptions};
    use super::*;

    /// The player on its own thread reports what it reports played tick by tick, bit
    /// for bit: the figures, a miss of the bounds, and a limit the player hits (after
    /// the ticks before it were within the bounds, or not).
    #[test]
    fn a_pipelined_measurement_is_the_measurement_in_turn() {
        let signal = stroke(30.0);
        let encoded = encode(&signal, fields(), &KeyframeOptions::default()).unwrap();
        let stim = Stimulus::decode(&encoded.bytes).unwrap();
        let fs = KeyframeOptions::default().full_scale_ma;
        let tight = Limits {
            i2t_budget_ma2s: 2_000_000,
            ..Limits::SLEEVE
        };
        let low_peak = Limits {
            peak_ma: 500,
            ..Limits::SLEEVE
        };
        let cases = [
            (Limits::SLEEVE, None, "figures"),
            (Limits::SLEEVE, Some((0.005, 0.02)), "figures"),
            (Limits::SLEEVE, Some((0.0005, 0.02)), "miss"),
            (Limits::SLEEVE, Some((0.005, 0.001)), "miss"),
            (tight, None, "thermal"),
            (low_peak, None, "peak"),
            // Missed before the peak: the miss, as in turn.
            (low_peak, Some((1e-6, 1e-6)), "miss"),
        ];
        for (limits, bounds, expected) in cases {
            let device = DeviceConfig {
                full_scale_ma: fs,
                limits,
            };
            let ticks = signal.len().max(stim.header().playback_ms() as usize + 1);
            let errors = || PlaybackErrors::new(&signal, fs, bounds, ticks);
            let in_turn = measure_in_turn(&stim, &device, errors());
            let pipelined = measure_pipelined(&stim, &device, errors());
            let outcome = match &in_turn {
                Ok((rms, _)) if rms.is_infinite() => "miss",
                Ok(_) => "figures",
                Err(KeyframeError::LimitHit(kind)) => kind,
                Err(_) => "error",
            };
            assert_eq!(outcome, expected, "{limits:?} {bounds:?}");
            match (in_turn, pipelined) {
                (Ok(a), Ok(b)) => {
                    assert_eq!(
                        (a.0.to_bits(), a.1.to_bits()),
                        (b.0.to_bits(), b.1.to_bits())
                    );
                }
                (a, b) => assert_eq!(format!("{a:?}"), format!("{b:?}")),
            }
        }
    }
}
