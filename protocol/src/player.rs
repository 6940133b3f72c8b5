//! The fixed-point player: a stimulus in, eight 12-bit output codes per 1 kHz tick out.
//!
//! The same code runs in the firmware's timer interrupt and in `touchc render`, so
//! it uses integer arithmetic only (no floats, no 64-bit division) and produces
//! bit-identical codes on x86 and on the Cortex-M4.
//!
//! Per tick and channel:
//! 1. interpolate linearly between the two keyframes around the tick (Q15);
//! 2. convert to microamperes and apply the ramp-in envelope (0 A to the signal
//!    over `ramp_ms`);
//! 3. enforce the limits, the stricter of the stimulus's and the device's: clamp to
//!    the peak (rounded down to a whole output code), clamp the change since the last tick to the slew bound (less one
//!    output step, so the step still fits after rounding to a code), and account
//!    the thermal I^2 t budget in the device's [`Thermal`] state. Once the heat
//!    leaves too little budget for one more tick and a ramp down, the next tick
//!    is not played: the player ramps down from the last one instead, so the heat
//!    never passes the budget. While playing, any limit hit is a [`Fault`]: the
//!    player reports it once and ramps every channel from where it is to 0 A;
//! 4. convert to a DAC/PWM code, 2048 = 0 A, 0 and 4095 = -/+ device full scale.
//!
//! After the last keyframe, and after [`Player::stop`], the outputs ramp linearly
//! from their last value to 0 A over `ramp_ms` (still slew-limited), then the player
//! reports [`Status::Finished`] and emits [`IDLE_CODE`] forever.

//!
//! Steps 1 to 4 and the ramp down are in the `tick` module; the peak, slew and
//! heat bounds they enforce in `bounds`.

mod bounds;
mod tick;

use crate::stimulus::Keyframes;
use crate::thermal::{budget_ma2ms, continuous_ma2, Thermal};
use crate::{Limits, Stimulus, CHANNELS, IDLE_CODE};
pub use bounds::{peak_bound_ua, slew_bound_ua};
use bounds::{ramp_down_ma2ms, trip_ma2ms};

/// Largest output code (12-bit converters).
pub const MAX_CODE: u16 = 4095;

/// What the output hardware can do, and its own hard limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceConfig {
    /// Current at codes 0 and 4095 (negative and positive), mA.
    pub full_scale_ma: u16,
    /// The device's hard limits; the player enforces the stricter of these and the
    /// stimulus's.
    pub limits: Limits,
}

impl Default for DeviceConfig {
    /// The sleeve: 1 A full scale (LM675T at 1 A/V), [`Limits::SLEEVE`].
    fn default() -> Self {
        DeviceConfig {
            full_scale_ma: 1000,
            limits: Limits::SLEEVE,
        }
    }
}

/// Which limit was hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LimitKind {
    /// The current exceeded the peak limit.
    Peak,
    /// The current changed faster than the slew limit.
    Slew,
    /// The thermal I^2 t budget would not carry another tick and the ramp down.
    Thermal,
}

/// A limit hit while playing: the player ramps to 0 A after reporting it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fault {
    /// Which limit.
    pub kind: LimitKind,
    /// The first channel (in channel order) that hit it.
    pub channel: u8,
}

/// The player's state after a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status {
    /// Playing the signal (including the ramp in).
    Playing,
    /// A limit was hit at this tick; the player now ramps down. Reported once.
    Fault(Fault),
    /// Ramping to 0 A after the end, a stop, or a fault.
    RampingDown,
    /// All outputs are at 0 A and stay there.
    Finished,
}

/// One tick's output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick {
    /// The eight output codes, channel order.
    pub codes: [u16; CHANNELS],
    /// The state after this tick.
    pub status: Status,
}

/// Where the codes go: PWM compare registers, DAC, a test buffer.
pub trait OutputSink {
    /// Presents one frame; all eight channels must change together.
    fn write(&mut self, codes: &[u16; CHANNELS]);
}

/// Where the keyframes come from.
#[derive(Debug, Clone)]
enum Source<'a> {
    /// A stimulus file.
    Stored(Keyframes<'a>),
    /// Handed in one by one while playing ([`Player::live`]): the keyframe after `b`,
    /// once it arrived.
    Live(Option<[i16; CHANNELS]>),
}

/// How a live player ([`Player::live`]) plays the keyframes it is handed: the
/// fields of a stimulus header that a stream has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LiveParams {
    /// Time between keyframes, ms (1..=1000).
    pub keyframe_period_ms: u16,
    /// Ramp from 0 A in, and back to 0 A at the end, ms.
    pub ramp_ms: u16,
    /// Current that the Q15 value 32768 stands for, mA.
    pub full_scale_ma: u16,
    /// The limits the keyframes were made for (the stricter of these and the
    /// device's apply).
    pub limits: Limits,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Signal,
    RampDown { from: [i32; CHANNELS], step: u32 },
    Done,
}

/// Plays one stimulus, one [`Player::tick`] per millisecond.
///
/// A plain struct without allocation (about 250 bytes), so the firmware can keep it
/// in a static and step it from an interrupt. It carries the device's [`Thermal`]
/// state while it plays: [`Player::new`] starts from a cold coil,
/// [`Player::with_thermal`] from the device's, and [`Player::thermal`] hands it back.
#[derive(Debug, Clone)]
pub struct Player<'a> {
    source: Source<'a>,
    /// A live player reached a keyframe boundary without the next keyframe.
    underrun: bool,
    /// Keyframe values around the current tick, Q15.
    a: [i32; CHANNELS],
    b: [i32; CHANNELS],
    period: u32,
    phase: u32,
    ramp_ms: u32,
    /// Ticks emitted while in [`Mode::Signal`].
    t: u32,
    duration_ms: u32,
    /// Q15 -> uA multiplier: the stimulus full scale in uA (at most 10^7, so a
    /// 32 x 32 -> 64-bit multiply on the Cortex-M4).
    full_scale_ua: i32,
    peak_ua: i32,
    /// The slew bound less one output step (see [`slew_bound_ua`]).
    slew_ua: i32,
    /// The bucket's leak per tick, mA^2.
    cool_ma2: u64,
    /// Heat above which no further signal tick is played: the budget less the most
    /// one tick and a ramp down can add (see [`trip_ma2ms`]).
    trip_ma2ms: u64,
    /// The first channel whose heat passed `trip_ma2ms` (its next signal tick
    /// becomes a thermal fault).
    hot: Option<u8>,
    /// The budget cannot carry one tick and the ramp down after it: nothing moves.
    starved: bool,
    /// Half an output step plus one, uA: a code stands for at most this much more
    /// current than the value it was rounded from.
    half_step_ua: u32,
    /// uA -> code offset multiplier, 2048 * 2^32 / device full scale in uA.
    code_mul: i64,
    thermal: Thermal,
    out: [i32; CHANNELS],
    mode: Mode,
    fault: Option<Fault>,
}

impl<'a> Player<'a> {
    /// Prepares to play `stimulus` on `device` from a cold coil; the first
    /// [`Player::tick`] starts the ramp in.
    pub fn new(stimulus: &Stimulus<'a>, device: &DeviceConfig) -> Self {
        Player::with_thermal(stimulus, device, Thermal::COLD)
    }

    /// Prepares to play `stimulus` on `device` whose coils hold `thermal`'s heat.
    ///
    /// Whether the device should start at all is [`Thermal::check_start`]'s call;
    /// whatever the heat, the player itself never lets it pass the budget.
    pub fn with_thermal(stimulus: &Stimulus<'a>, device: &DeviceConfig, thermal: Thermal) -> Self {
        let h = stimulus.header();
        let mut keyframes = stimulus.keyframes();
        let first = widen(keyframes.next().unwrap_or([0; CHANNELS]));
        let second = keyframes.next().map(widen).unwrap_or(first);
        let params = LiveParams {
            keyframe_period_ms: h.keyframe_period_ms,
            ramp_ms: h.ramp_ms,
            full_scale_ma: h.full_scale_ma,
            limits: h.limits,
        };
        let source = Source::Stored(keyframes);
        Player::build(
            source,
            &params,
            h.duration_ms,
            [first, second],
            device,
            thermal,
        )
    }

    /// A player whose keyframes are handed in while it plays ([`Player::push_keyframe`]),
    /// starting between `first` and `second`: a stream. It plays until stopped; at a
    /// keyframe boundary without the next keyframe it holds the last one and reports
    /// [`Player::underrun`] (the caller ramps it down).
    pub fn live(
        params: &LiveParams,
        first: [i16; CHANNELS],
        second: [i16; CHANNELS],
        device: &DeviceConfig,
        thermal: Thermal,
    ) -> Player<'static> {
        Player::build(
            Source::Live(None),
            params,
            u32::MAX,
            [widen(first), widen(second)],
            device,
            thermal,
        )
    }

    /// True while a live player has room for the next keyframe.
    pub fn wants_keyframe(&self) -> bool {
        matches!(self.source, Source::Live(None))
    }

    /// Hands a live player its next keyframe; returns it back if the player holds one
    /// already (or plays a stimulus).
    pub fn push_keyframe(&mut self, k: [i16; CHANNELS]) -> Result<(), [i16; CHANNELS]> {
        match &mut self.source {
            Source::Live(next @ None) => {
                *next = Some(k);
                Ok(())
            }
            _ => Err(k),
        }
    }

    /// True once a live player met a keyframe boundary without its next keyframe.
    pub fn underrun(&self) -> bool {
        self.underrun
    }

    fn build(
        source: Source<'a>,
        h: &LiveParams,
        duration_ms: u32,
        [first, second]: [[i32; CHANNELS]; 2],
        device: &DeviceConfig,
        thermal: Thermal,
    ) -> Self {
        let limits = h.limits.min(device.limits);
        let device_ua = i64::from(device.full_scale_ma.max(1)) * 1000;
        let (step_ua, half_step_ua) = output_step_ua(device_ua);
        let ramp_ms = u32::from(h.ramp_ms.max(1));
        let peak_ua = peak_bound_ua(limits.peak_ma, device_ua);
        let slew_ua = slew_bound_ua(limits.slew_ma_per_ms, step_ua);
        let mut player = Player {
            source,
            underrun: false,
            a: first,
            b: second,
            period: u32::from(h.keyframe_period_ms.max(1)),
            phase: 0,
            ramp_ms,
            t: 0,
            duration_ms,
            full_scale_ua: i32::from(h.full_scale_ma) * 1000,
            peak_ua,
            slew_ua,
            cool_ma2: continuous_ma2(&limits),
            trip_ma2ms: trip_ma2ms(&limits, peak_ua, slew_ua, ramp_ms, half_step_ua),
            hot: None,
            starved: false,
            half_step_ua,
            code_mul: (2048i64 << 32) / device_ua,
            thermal,
            out: [0; CHANNELS],
            mode: Mode::Signal,
            fault: None,
        };
        player.starved = budget_ma2ms(&limits) < player.reserve_ma2ms();
        player.start_from(&thermal);
        if player.slew_ua == 0 || player.peak_ua == 0 {
            // Nothing may move: finish at once rather than pretend to play.
            player.mode = Mode::Done;
        }
        player
    }

    /// Gives a player that has not ticked yet the coils' heat as it is now: it is
    /// then the player [`Player::with_thermal`] (or [`Player::live`]) would have
    /// built from `thermal`. A firmware builds the next player ahead, outside its
    /// tick, from any heat, and hands it the device's at the tick that starts it:
    /// a copy and a comparison, where building it costs divisions and the first
    /// keyframes' decoding. Call it before the first [`Player::tick`] only.
    pub fn start_from(&mut self, thermal: &Thermal) {
        self.thermal = *thermal;
        let (channel, heat) = self.thermal.hottest();
        // Too hot already, or a budget that cannot carry even one tick and the ramp
        // down after it: the first tick is a thermal fault and nothing moves.
        self.hot = (heat > self.trip_ma2ms || self.starved).then_some(channel);
    }

    /// Requests a stop: the outputs ramp from where they are to 0 A.
    pub fn stop(&mut self) {
        if self.mode == Mode::Signal {
            self.mode = Mode::RampDown {
                from: self.out,
                step: 0,
            };
        }
    }

    /// True once every output is back at 0 A for good.
    pub fn is_done(&self) -> bool {
        self.mode == Mode::Done
    }

    /// The first limit hit, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// The coils' heat after the last tick (the device takes it back when the player
    /// is done, and keeps cooling it).
    pub fn thermal(&self) -> Thermal {
        self.thermal
    }

    /// The outputs of the last tick, microamperes.
    pub fn output_ua(&self) -> [i32; CHANNELS] {
        self.out
    }

    /// Computes the next tick and hands its codes to `sink`.
    pub fn tick_into(&mut self, sink: &mut impl OutputSink) -> Status {
        let tick = self.tick();
        sink.write(&tick.codes);
        tick.status
    }

    /// Computes the next 1 kHz tick.
    pub fn tick(&mut self) -> Tick {
        let status = match self.mode {
            Mode::Signal => self.signal_tick(),
            Mode::RampDown { from, step } => self.ramp_tick(from, step),
            Mode::Done => {
                self.cool();
                Status::Finished
            }
        };
        Tick {
            codes: self.codes(),
            status,
        }
    }

    /// The most one more tick and a ramp down can add, mA^2 ms (see [`trip_ma2ms`]).
    fn reserve_ma2ms(&self) -> u64 {
        ramp_down_ma2ms(self.peak_ua, self.slew_ua, self.ramp_ms, self.half_step_ua)
    }
}

/// Iterates ticks until (and including) the first [`Status::Finished`].
impl Iterator for Player<'_> {
    type Item = Tick;

    fn next(&mut self) -> Option<Tick> {
        if self.is_done() {
            return None;
        }
        Some(self.tick())
    }
}

fn widen(k: [i16; CHANNELS]) -> [i32; CHANNELS] {
    k.map(i32::from)
}

/// One output step of a device of `device_ua` full scale (its full scale / 2048,
/// rounded up), and half of it plus one: the most a code stands for beyond the value
/// it was rounded from, uA.
#[inline(always)]
fn output_step_ua(device_ua: i64) -> (u32, u32) {
    let step_ua = ((device_ua + 2047) / 2048) as u32;
    (step_ua, step_ua / 2 + 1)
}

/// The most the player's heat accounting adds to a tick's current on a device of
/// `device_full_scale_ma`, uA: each tick is accounted at the current its code stands
/// for (up to half an output step above the value) rounded up to a whole mA. A
/// compiler that fits a signal to the thermal budget in real numbers leaves this much
/// room per tick, or a long touch trips the player's limit.
pub fn heat_accounting_margin_ua(device_full_scale_ma: u16) -> u32 {
    let (_, half_step_ua) = output_step_ua(i64::from(device_full_scale_ma.max(1)) * 1000);
    half_step_ua + 999
}

/// The current a code stands for on a device, in amperes (for plots and CSV).
pub fn code_to_amps(code: u16, device_full_scale_ma: u16) -> f64 {
    (f64::from(code) - f64::from(IDLE_CODE)) / 2048.0 * f64::from(device_full_scale_ma) / 1000.0
}
