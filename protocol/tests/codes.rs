//! The player's limits where they reach the coil: on the output codes, at any device
//! full scale, with the heat measured every tick by meters of this file's own.
//!
//! Nothing here calls the player's or the thermal module's arithmetic to decide what
//! is right: the bounds are derived from the limits and the code scale (a code stands
//! for `(code - 2048) * full_scale / 2048`), and the heat is re-computed from
//! `SPEC.md`'s description of the leaky I^2 t bucket, once on the currents the codes
//! stand for (what the coil gets) and once with the accounting the spec prescribes
//! (which must equal the device's own count exactly).

use proptest::prelude::*;
use touch_protocol::player::LimitKind;
use touch_protocol::{stimulus, DeviceConfig, Limits, Player, Status, Stimulus, Thermal, CHANNELS};

/// The tests' stimuli: the fields the player reads as given, the rest fixed.
fn builder(
    period: u16,
    ramp: u16,
    full_scale_ma: u16,
    limits: Limits,
) -> stimulus::Builder<'static> {
    stimulus::Builder::new("codes", period)
        .ramp_ms(ramp)
        .full_scale_ma(full_scale_ma)
        .layout("t", 1)
        .limits(limits)
}

/// The code for 0 A, written out rather than imported: the test's own scale.
const ZERO: i64 = 2048;

/// The largest code step a slew limit allows on a device: the step of `slew` mA in
/// codes of `fs / 2048` mA, rounded down (102 for 50 mA/ms at 1 A full scale: 103
/// codes would be 50.3 mA).
fn max_code_step(slew_ma: u16, fs_ma: u16) -> i64 {
    i64::from(slew_ma) * 2048 / i64::from(fs_ma)
}

/// The largest distance from [`ZERO`] a peak limit allows, in codes, rounded down.
fn max_code_offset(peak_ma: u16, fs_ma: u16) -> i64 {
    i64::from(peak_ma) * 2048 / i64::from(fs_ma)
}

/// The heat the coil gets, from the codes alone: per channel a bucket of
/// `I^2 - continuous^2` that never drains below empty, with `I` the current the code
/// stands for. Exact integers: the unit is mA^2 ms / 2048^2.
struct CoilMeter {
    heat: [i128; CHANNELS],
    fs_ma: i128,
}

impl CoilMeter {
    fn new(fs_ma: u16) -> Self {
        CoilMeter {
            heat: [0; CHANNELS],
            fs_ma: i128::from(fs_ma),
        }
    }

    /// One millisecond at these codes; `continuous_ma` is the rating that leaks.
    fn tick(&mut self, codes: &[u16; CHANNELS], continuous_ma: u16) {
        let cool = (i128::from(continuous_ma) * 2048).pow(2);
        for (h, &code) in self.heat.iter_mut().zip(codes) {
            let i = (i128::from(code) - i128::from(ZERO)) * self.fs_ma;
            *h = (*h + i * i - cool).max(0);
        }
    }

    /// Asserts every channel at or under `budget_ma2s`, or at or under its heat in
    /// `start` (a play that starts above its budget, left there by a stimulus with a
    /// looser one, may only cool).
    fn check(
        &self,
        budget_ma2s: u32,
        start: &[i128; CHANNELS],
        what: &str,
    ) -> Result<(), TestCaseError> {
        let budget = i128::from(budget_ma2s) * 1000 * 2048 * 2048;
        for (c, &h) in self.heat.iter().enumerate() {
            prop_assert!(
                h <= budget.max(start[c]),
                "{what}: channel {c} at {:.1} mA^2 s over a {budget_ma2s} mA^2 s budget",
                h as f64 / 2048.0 / 2048.0 / 1000.0
            );
        }
        Ok(())
    }
}

/// The device's count of the heat as `SPEC.md` prescribes it, from the player's
/// outputs: `heat = max(0, heat + acc(ua)^2 - continuous^2)` with `acc(ua) =
/// ceil((|ua| + step / 2 + 1) / 1000)` mA and `step` the output step rounded up, uA;
/// idle ticks only cool.
struct SpecMeter {
    heat: [u64; CHANNELS],
    step_ua: u64,
}

impl SpecMeter {
    fn new(fs_ma: u16) -> Self {
        SpecMeter {
            heat: [0; CHANNELS],
            step_ua: (u64::from(fs_ma) * 1000).div_ceil(2048),
        }
    }

    fn play(&mut self, ua: &[i32; CHANNELS], continuous_ma: u16) {
        let cool = u64::from(continuous_ma).pow(2);
        for (h, &v) in self.heat.iter_mut().zip(ua) {
            let acc = (u64::from(v.unsigned_abs()) + self.step_ua / 2 + 1).div_ceil(1000);
            *h = (*h + acc * acc).saturating_sub(cool);
        }
    }

    fn idle(&mut self, continuous_ma: u16) {
        let cool = u64::from(continuous_ma).pow(2);
        for h in &mut self.heat {
            *h = h.saturating_sub(cool);
        }
    }

    /// The hottest channel (the first of equals) and its heat.
    fn hottest(&self) -> (u8, u64) {
        let mut best = (0u8, 0u64);
        for (c, &h) in self.heat.iter().enumerate() {
            if h > best.1 || c == 0 {
                best = (c as u8, h);
            }
        }
        best
    }
}

fn keyframes(max_len: usize) -> impl Strategy<Value = Vec<[i16; CHANNELS]>> {
    prop::collection::vec(prop::array::uniform8(any::<i16>()), 1..max_len)
}

/// Limits with budgets small enough that random stimuli trip them often.
fn limits() -> impl Strategy<Value = Limits> {
    // Some budgets too small to carry one tick and a ramp down (even 0), most that a
    // stimulus reaches in a few hundred ms, a few the sleeve's size.
    let budget = prop_oneof![
        1 => Just(0u32),
        2 => 0u32..2_000,
        4 => 0u32..200_000,
        4 => 0u32..2_000_000,
        2 => 0u32..50_000_000,
    ];
    (1u16..3000, 1u16..200, 0u16..1500, budget).prop_map(|(p, s, c, b)| Limits {
        peak_ma: p,
        slew_ma_per_ms: s,
        continuous_ma: c,
        i2t_budget_ma2s: b,
    })
}

/// One stimulus to play: keyframes, period, ramp, its own full scale and limits, and
/// when (if ever) the button stops it.
#[derive(Debug, Clone)]
struct Play {
    kf: Vec<[i16; CHANNELS]>,
    period: u16,
    ramp: u16,
    full_scale_ma: u16,
    limits: Limits,
    stop_at: Option<u32>,
    /// Idle milliseconds before this play starts.
    idle_before: u32,
}

fn play() -> impl Strategy<Value = Play> {
    (
        keyframes(12),
        1u16..60,
        1u16..300,
        100u16..3000,
        limits(),
        prop::option::of(0u32..800),
        prop_oneof![Just(0u32), 0u32..3000],
    )
        .prop_map(
            |(kf, period, ramp, full_scale_ma, limits, stop_at, idle_before)| Play {
                kf,
                period,
                ramp,
                full_scale_ma,
                limits,
                stop_at,
                idle_before,
            },
        )
}

/// Plays `plays` one after the other on one device, its coils' heat carried from each
/// to the next (cooling while idle), and checks every tick: the code step within the
/// slew limit, the code within the peak, the heat within the budget on both meters,
/// the device's heat equal to the spec's count, and the start rule against the
/// spec's count. Returns the ticks played.
fn play_on_device(device: DeviceConfig, plays: &[Play]) -> Result<u64, TestCaseError> {
    let fs = device.full_scale_ma;
    let mut coil = CoilMeter::new(fs);
    let mut spec = SpecMeter::new(fs);
    let mut thermal = Thermal::COLD;
    let mut ticks = 0u64;
    for (i, p) in plays.iter().enumerate() {
        // The device's continuous rating leaks while idle (`Thermal::idle_tick`).
        for _ in 0..p.idle_before {
            thermal.idle_tick(&device.limits);
            spec.idle(device.limits.continuous_ma);
            coil.tick(&[ZERO as u16; CHANNELS], device.limits.continuous_ma);
        }
        prop_assert_eq!(
            thermal.heat_ma2ms(),
            spec.heat,
            "play {}: heat after idling",
            i
        );

        // The start rule: refused while any channel is above half the device's budget,
        // naming the hottest.
        let half = u64::from(device.limits.i2t_budget_ma2s) * 1000 / 2;
        let (hot_c, hot_h) = spec.hottest();
        match thermal.check_start(&device.limits) {
            Ok(()) => prop_assert!(hot_h <= half, "play {i}: started at {hot_h} > {half}"),
            Err(e) => {
                prop_assert!(hot_h > half, "play {i}: refused at {hot_h} <= {half}");
                prop_assert_eq!(e.channel, hot_c, "play {}: the hottest channel", i);
            }
        }

        // Whatever the rule says, the player itself must hold the budget from any heat.
        let bytes = builder(p.period, p.ramp, p.full_scale_ma, p.limits)
            .encode(&p.kf)
            .expect("encodable");
        let s = Stimulus::decode(&bytes).expect("decodable");
        let eff = p.limits.min(device.limits);
        let (step_max, peak_max) = (
            max_code_step(eff.slew_ma_per_ms, fs),
            max_code_offset(eff.peak_ma, fs),
        );
        let mut player = Player::with_thermal(&s, &device, thermal);
        // Built ahead from a cold coil and handed the heat at its start: the same
        // player, field for field.
        let mut ahead = Player::new(&s, &device);
        ahead.start_from(&thermal);
        prop_assert_eq!(format!("{ahead:?}"), format!("{player:?}"), "play {}", i);
        let (coil_start, spec_start) = (coil.heat, spec.heat);
        let mut prev = [ZERO as u16; CHANNELS];
        let mut n = 0u32;
        let bound = s.header().playback_ms()
            + 3
            + 2 * u32::from(eff.peak_ma) / u32::from(eff.slew_ma_per_ms.max(1));
        loop {
            if Some(n) == p.stop_at {
                player.stop();
            }
            let done_before = player.is_done();
            let t = player.tick();
            n += 1;
            ticks += 1;
            for (c, (&code, &before)) in t.codes.iter().zip(&prev).enumerate() {
                let (code, before) = (i64::from(code), i64::from(before));
                prop_assert!(
                    (code - before).abs() <= step_max,
                    "play {i} tick {n} channel {c}: {before} -> {code} codes, over {step_max} ({} mA/ms at {fs} mA full scale)",
                    eff.slew_ma_per_ms
                );
                prop_assert!(
                    (code - ZERO).abs() <= peak_max,
                    "play {i} tick {n} channel {c}: code {code} over the {} mA peak ({peak_max} codes)",
                    eff.peak_ma
                );
            }
            prev = t.codes;
            let fault_at_rest = matches!(t.status, Status::Fault(_)) && player.is_done();
            if done_before || fault_at_rest {
                // Once finished the player is idle, and so is a thermal fault with
                // every output at 0 A (nothing to ramp down from): they only cool.
                prop_assert_eq!(t.codes, [ZERO as u16; CHANNELS]);
                spec.idle(eff.continuous_ma);
            } else {
                spec.play(&player.output_ua(), eff.continuous_ma);
            }
            coil.tick(&t.codes, eff.continuous_ma);
            coil.check(
                eff.i2t_budget_ma2s,
                &coil_start,
                &format!("play {i} tick {n}"),
            )?;
            prop_assert_eq!(
                player.thermal().heat_ma2ms(),
                spec.heat,
                "play {} tick {}: the device's heat",
                i,
                n
            );
            for (c, &h) in spec.heat.iter().enumerate() {
                prop_assert!(
                    h <= (u64::from(eff.i2t_budget_ma2s) * 1000).max(spec_start[c]),
                    "play {i} tick {n} channel {c}: accounted heat {h} over the budget"
                );
            }
            if t.status == Status::Finished {
                break;
            }
            prop_assert!(
                n <= bound,
                "play {i}: still running after {n} ticks (bound {bound})"
            );
        }
        thermal = player.thermal();
    }
    Ok(ticks)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// One play from a cold coil, at any device full scale, limits and stop.
    #[test]
    fn codes_stay_within_the_limits_at_any_full_scale(
        p in play(), dev_limits in limits(), dev_fs in 100u16..3000,
    ) {
        let device = DeviceConfig { full_scale_ma: dev_fs, limits: dev_limits };
        play_on_device(device, &[Play { idle_before: 0, ..p }])?;
    }

    /// Several plays on one device: each after the last one's heat, some starting hot
    /// (`Player::with_thermal`), some refused by the start rule but played anyway.
    #[test]
    fn codes_and_heat_stay_within_the_limits_from_a_hot_coil(
        plays in prop::collection::vec(play(), 2..5), dev_limits in limits(), dev_fs in 100u16..3000,
    ) {
        let device = DeviceConfig { full_scale_ma: dev_fs, limits: dev_limits };
        play_on_device(device, &plays)?;
    }
}

/// The sleeve's own scale: at 1 A full scale the 50 mA/ms limit allows 102 codes per
/// tick (49.8 mA) and never 103 (50.3 mA). A 1 ms ramp down from +1 A (a stop) and
/// from -1 A (the end) is slew-limited all the way: steps at the limit, none over.
#[test]
fn a_full_scale_ramp_down_at_one_amp_moves_at_most_102_codes_per_tick() {
    assert_eq!(max_code_step(Limits::SLEEVE.slew_ma_per_ms, 1000), 102);
    // +1 A and -1 A reached at 20 mA/ms (within the slew), each held 100 ms.
    let kf = [0, 32767, 32767, -32768, -32768].map(|v: i16| [v; CHANNELS]);
    let bytes = builder(100, 1, 1000, Limits::SLEEVE).encode(&kf).unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut widest = 0;
    for stop_at in [Some(150), None] {
        let mut p = Player::new(&s, &DeviceConfig::default());
        let mut prev = ZERO;
        for n in 0.. {
            if Some(n) == stop_at {
                p.stop();
            }
            let Some(t) = p.next() else { break };
            assert!(!matches!(t.status, Status::Fault(_)), "{:?}", t.status);
            let code = i64::from(t.codes[0]);
            widest = widest.max((code - prev).abs());
            prev = code;
        }
    }
    assert!(widest <= 102, "a step of {widest} codes");
    assert!(
        widest >= 101,
        "the ramp down never reached the limit: {widest} codes"
    );
}

/// A budget too small for one tick and the ramp down after it: nothing plays (a
/// thermal fault on the first tick, every output at 0 A), where playing one tick
/// would already pass it.
#[test]
fn a_budget_too_small_for_one_tick_and_a_ramp_plays_nothing() {
    let tiny = Limits {
        continuous_ma: 0,
        i2t_budget_ma2s: 1,
        ..Limits::SLEEVE
    };
    let bytes = builder(1000, 100, 1000, tiny)
        .encode(&[[32767; CHANNELS]; 2])
        .unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut p = Player::new(&s, &DeviceConfig::default());
    let mut meter = CoilMeter::new(1000);
    let first = p.tick();
    assert!(
        matches!(first.status, Status::Fault(f) if f.kind == LimitKind::Thermal),
        "{:?}",
        first.status
    );
    meter.tick(&first.codes, 0);
    for t in p.by_ref() {
        meter.tick(&t.codes, 0);
    }
    assert_eq!(meter.heat, [0; CHANNELS]);
    assert_eq!(p.thermal(), Thermal::COLD);
}

/// A coil left at the budget by one play: the next play, started from that heat
/// without asking the start rule, is a thermal fault on its first tick, and the heat
/// never passes the budget.
#[test]
fn a_play_started_on_a_hot_coil_stops_at_once() {
    let hot = Limits {
        continuous_ma: 100,
        i2t_budget_ma2s: 500_000,
        ..Limits::SLEEVE
    };
    let device = DeviceConfig {
        full_scale_ma: 1000,
        limits: hot,
    };
    // Channel 5 alone at 1 A (ramped in over 100 ms, within the slew): it trips on
    // the heat, the others stay cold.
    let mut frame = [0i16; CHANNELS];
    frame[5] = 32767;
    let bytes = builder(1000, 100, 1000, hot).encode(&[frame; 3]).unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut first = Player::new(&s, &device);
    let mut meter = CoilMeter::new(1000);
    let mut tripped = None;
    for t in first.by_ref() {
        meter.tick(&t.codes, hot.continuous_ma);
        if let Status::Fault(f) = t.status {
            tripped = Some((f.kind, f.channel));
        }
    }
    assert_eq!(tripped, Some((LimitKind::Thermal, 5)));
    let heat = first.thermal();
    assert_eq!(heat.hottest().0, 5);
    assert!(heat.check_start(&hot).is_err(), "{:?}", heat.heat_ma2ms());

    let mut second = Player::with_thermal(&s, &device, heat);
    let mut ahead = Player::new(&s, &device);
    ahead.start_from(&heat);
    assert_eq!(format!("{ahead:?}"), format!("{second:?}"));
    let t = second.tick();
    assert!(
        matches!(t.status, Status::Fault(f) if f.kind == LimitKind::Thermal && f.channel == 5),
        "{:?}",
        t.status
    );
    meter.tick(&t.codes, hot.continuous_ma);
    for t in second.by_ref() {
        meter.tick(&t.codes, hot.continuous_ma);
        meter
            .check(hot.i2t_budget_ma2s, &[0; CHANNELS], "second play")
            .unwrap();
    }
    assert_eq!(t.codes, [ZERO as u16; CHANNELS]);
}
