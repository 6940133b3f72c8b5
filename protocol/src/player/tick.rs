//! One tick's arithmetic, steps 1 to 4 of the player (see the parent module):
//! interpolate, apply the ramp-in envelope, enforce the limits and account the
//! heat, convert to codes; and the ramp down to 0 A after the end, a stop or a
//! fault.

use super::bounds::accounted_ma;
use super::{widen, Fault, LimitKind, Mode, Player, Source, Status, MAX_CODE};
use crate::{CHANNELS, IDLE_CODE};

impl Player<'_> {
    pub(super) fn signal_tick(&mut self) -> Status {
        if let Some(channel) = self.hot {
            // Too hot for another tick: one more at any current, then a ramp down,
            // could pass the budget; a ramp down from the last tick's outputs cannot.
            let f = Fault {
                kind: LimitKind::Thermal,
                channel,
            };
            self.fault.get_or_insert(f);
            if self.out == [0; CHANNELS] {
                // Nothing to ramp down from (a start on a hot coil): every output is
                // at 0 A already, so this tick is idle and the player is done.
                self.cool();
                self.mode = Mode::Done;
            } else {
                self.ramp_tick(self.out, 0);
            }
            return Status::Fault(f);
        }
        // Ramp-in envelope, Q16: (t + 1) / ramp, reaching 1 after `ramp_ms` ticks.
        let t1 = self.t.saturating_add(1);
        let env = if t1 < self.ramp_ms {
            (t1 << 16) / self.ramp_ms
        } else {
            1 << 16
        };
        let mut fault = None;
        // The period is a u16 of at least 1 already; saying so here lets the compiler
        // drop the division's zero and overflow checks from every channel.
        let period = self.period.clamp(1, u32::from(u16::MAX)) as i32;
        let phase = self.phase as i32;
        for c in 0..CHANNELS {
            let (a, b) = (self.a[c], self.b[c]);
            // |b - a| < 2^16 and phase < period <= 1000: the product fits in i32.
            let q = a + (b - a) * phase / period;
            let ua = ((i64::from(q) * i64::from(self.full_scale_ua)) >> 15) as i32;
            let target = ((i64::from(ua) * i64::from(env)) >> 16) as i32;
            let (value, hit) = self.clamp(c, target);
            self.out[c] = value;
            self.heat(c, value);
            if fault.is_none() {
                fault = hit.map(|kind| Fault {
                    kind,
                    channel: c as u8,
                });
            }
        }
        self.advance();
        if let Some(f) = fault {
            self.fault.get_or_insert(f);
            self.mode = Mode::RampDown {
                from: self.out,
                step: 0,
            };
            return Status::Fault(f);
        }
        Status::Playing
    }

    /// Moves to the next tick's keyframe position; at the end, starts the ramp down.
    fn advance(&mut self) {
        if self.t >= self.duration_ms {
            self.mode = Mode::RampDown {
                from: self.out,
                step: 0,
            };
            return;
        }
        self.t = self.t.saturating_add(1);
        self.phase += 1;
        if self.phase == self.period {
            self.phase = 0;
            self.a = self.b;
            let next = match &mut self.source {
                Source::Stored(keyframes) => keyframes.next(),
                Source::Live(next) => {
                    let k = next.take();
                    self.underrun |= k.is_none();
                    k
                }
            };
            match next {
                Some(k) => self.b = widen(k),
                None => self.b = self.a,
            }
        }
    }

    pub(super) fn ramp_tick(&mut self, from: [i32; CHANNELS], step: u32) -> Status {
        let step = step.saturating_add(1);
        let left = self.ramp_ms.saturating_sub(step);
        let env = (left << 16) / self.ramp_ms;
        let mut all_zero = true;
        for (c, &from) in from.iter().enumerate() {
            let target = ((i64::from(from) * i64::from(env)) >> 16) as i32;
            // Limits still bound every output; hits while ramping down are not faults.
            let (value, _) = self.clamp(c, target);
            self.out[c] = value;
            self.heat(c, value);
            all_zero &= value == 0;
        }
        if left == 0 && all_zero {
            self.mode = Mode::Done;
            Status::Finished
        } else {
            self.mode = Mode::RampDown { from, step };
            Status::RampingDown
        }
    }

    /// Applies the peak and slew limits to channel `c`'s target.
    // Inlined: as a call it costs the signal tick some fifty instructions.
    #[inline(always)]
    fn clamp(&self, c: usize, target: i32) -> (i32, Option<LimitKind>) {
        let mut hit = None;
        let mut v = target;
        if v > self.peak_ua || v < -self.peak_ua {
            v = v.clamp(-self.peak_ua, self.peak_ua);
            hit = Some(LimitKind::Peak);
        }
        let prev = self.out[c];
        if v - prev > self.slew_ua || prev - v > self.slew_ua {
            v = v.clamp(prev - self.slew_ua, prev + self.slew_ua);
            hit = hit.or(Some(LimitKind::Slew));
        }
        (v, hit)
    }

    /// Accounts one tick at `ua` on channel `c`: the current the code stands for,
    /// rounded up to a whole mA, squared; notes the first channel too hot to play on.
    #[inline(always)]
    fn heat(&mut self, c: usize, ua: i32) {
        let ma = accounted_ma(ua.unsigned_abs(), self.half_step_ua);
        let h = self.thermal.add(c, ma * ma, self.cool_ma2);
        if h > self.trip_ma2ms && self.hot.is_none() {
            self.hot = Some(c as u8);
        }
    }

    /// One tick at 0 A.
    pub(super) fn cool(&mut self) {
        for h in &mut self.thermal.heat {
            *h = h.saturating_sub(self.cool_ma2);
        }
    }

    pub(super) fn codes(&self) -> [u16; CHANNELS] {
        let mut codes = [IDLE_CODE; CHANNELS];
        for (code, &ua) in codes.iter_mut().zip(&self.out) {
            let offset = (i64::from(ua) * self.code_mul + (1 << 31)) >> 32;
            *code = (i64::from(IDLE_CODE) + offset).clamp(0, i64::from(MAX_CODE)) as u16;
        }
        codes
    }
}
