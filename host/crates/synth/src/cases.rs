//! The synthetic cases of real touch that tracking is measured on (`touchc trade
//! --cases`, `docs/trade.md`): what captures of other sensors hold and the paper's
//! scenes do not (a flat hand with a weaker heel, rubs up to a vigorous 1 m/s, many
//! strokes in quick succession, fast swipes), each on both sensors and at both rates.

use super::{Fabric, Gesture, Sensor, SynthSpec, Tuning};

/// Rates every case is sampled at, Hz: the paper's sleeve and the other lab's grid.
pub const RATES_HZ: [f64; 2] = [20.0, 54.0];

/// Seconds of sensor noise before and after the touch: more than any tare window.
pub const QUIET_S: f64 = 1.5;

/// One synthetic case: a name, the sensor and rate, and the spec that generates it.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// What the case holds (`hand with heel`, `rub 0.3 m/s`, ...).
    pub name: String,
    /// The sensor imitated.
    pub sensor: Sensor,
    /// The rate it is sampled at, Hz.
    pub rate_hz: f64,
    /// The spec (seed 1; vary `seed` for more draws of the same case).
    pub spec: SynthSpec,
    /// What the case must show to pass.
    pub bar: Bar,
}

/// The bar a case is held to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bar {
    /// Tracking against the truth: recall, coverage, few splits, no merge, no false
    /// contact (the smooth cases).
    Tracking,
    /// Real-like touch on a fabric grid: recall and coverage, trajectories within 1.5
    /// times the true contacts (one per hand), and at most this many bytes per second
    /// of stimulus.
    RealLike {
        /// The most bytes per second the stimulus may take.
        max_bytes_per_s: f64,
    },
}

/// `gestures` with `tuning` on `sensor` at `rate_hz`, [`QUIET_S`] of quiet on each side.
pub fn spec(sensor: Sensor, rate_hz: f64, gestures: &[Gesture], tuning: Tuning) -> SynthSpec {
    SynthSpec {
        gestures: gestures.to_vec(),
        seed: 1,
        noise_psi: 0.003,
        quiet_frames: (rate_hz * QUIET_S).round() as usize,
        sensor,
        tuning,
        rate_hz: Some(rate_hz),
        ..SynthSpec::default()
    }
}

/// The touches of one sensor at one rate: a flat hand with a weaker heel, rubs whose
/// speed peaks at 0.3, 0.45, 0.6 and 1 m/s (real rubs reach 0.6 m/s at their 90th
/// percentile; 1 m/s is a vigorous one), 15 strokes back and forth with gaps of
/// 150-400 ms, each light, changing speed and wavering in pressure along its way, with
/// a dropout now and then, and 3 fast swipes at 2.5 m/s.
pub fn cases_on(sensor: Sensor, rate_hz: f64) -> Vec<Case> {
    let mut out = Vec::new();
    let mut add = |name: String, spec: SynthSpec| {
        out.push(Case {
            name,
            sensor,
            rate_hz,
            spec,
            bar: Bar::Tracking,
        })
    };
    add(
        "hand with heel".into(),
        spec(sensor, rate_hz, &[Gesture::Hand], Tuning::default()),
    );
    for v in [0.3, 0.45, 0.6, 1.0] {
        let t = Tuning {
            stroke_speed_mps: Some(v),
            ..Tuning::default()
        };
        add(
            format!("rub {v} m/s"),
            spec(sensor, rate_hz, &[Gesture::Rub], t),
        );
    }
    let t = Tuning {
        stroke_speed_mps: Some(0.3),
        strokes: Some(15),
        gap_s: Some(0.15),
        gap_max_s: Some(0.4),
        ..Tuning::default()
    };
    add(
        "15 strokes, gaps 150-400 ms".into(),
        SynthSpec {
            flicker: 2.0,
            ..spec(sensor, rate_hz, &[Gesture::Strokes], t)
        },
    );
    let t = Tuning {
        stroke_speed_mps: Some(2.5),
        ..Tuning::default()
    };
    add(
        "3 swipes 2.5 m/s".into(),
        spec(sensor, rate_hz, &[Gesture::Strokes], t),
    );
    out
}

/// The real-like touches of one sensor at one rate, read through a fabric grid
/// ([`Fabric`]): a flat hand held, a rub, pats, strokes, 15 separate strokes, a tickle
/// and a scratch on the bare grid, and strokes through fur. The held hand and the rub
/// begin with the hand already on the sensor, as most real captures do.
pub fn real_like_on(sensor: Sensor, rate_hz: f64) -> Vec<Case> {
    let bare = Some(Fabric::BARE);
    let held = Tuning {
        hold_s: Some(6.0),
        ..Tuning::default()
    };
    let rub = Tuning {
        hold_s: Some(6.0),
        stroke_speed_mps: Some(0.45),
        ..Tuning::default()
    };
    let fifteen = Tuning {
        stroke_speed_mps: Some(0.3),
        strokes: Some(15),
        gap_s: Some(0.15),
        gap_max_s: Some(0.4),
        ..Tuning::default()
    };
    let list = [
        ("held hand, fabric", Gesture::Hand, held, bare, true, 150.0),
        ("rub, fabric", Gesture::Rub, rub, bare, true, 150.0),
        (
            "pats, fabric",
            Gesture::Pat,
            Tuning::default(),
            bare,
            false,
            150.0,
        ),
        (
            "strokes, fabric",
            Gesture::Strokes,
            Tuning::default(),
            bare,
            false,
            150.0,
        ),
        (
            "15 strokes, fabric",
            Gesture::Strokes,
            fifteen,
            bare,
            false,
            150.0,
        ),
        (
            "tickle, fabric",
            Gesture::Tickle,
            Tuning::default(),
            bare,
            false,
            150.0,
        ),
        (
            "scratch, fabric",
            Gesture::Scratch,
            Tuning::default(),
            bare,
            false,
            200.0,
        ),
        (
            "strokes through fur",
            Gesture::Strokes,
            Tuning::default(),
            Some(Fabric::FUR),
            false,
            150.0,
        ),
    ];
    list.into_iter()
        .map(
            |(name, g, tuning, fabric, on_at_start, max_bytes_per_s)| Case {
                name: name.into(),
                sensor,
                rate_hz,
                spec: SynthSpec {
                    fabric,
                    begin_mid_touch: on_at_start,
                    ..spec(sensor, rate_hz, &[g], tuning)
                },
                bar: Bar::RealLike { max_bytes_per_s },
            },
        )
        .collect()
}

/// Every case on both sensors at both rates ([`RATES_HZ`]): the smooth ones
/// ([`cases_on`]), then the real-like ones ([`real_like_on`]).
pub fn cases() -> Vec<Case> {
    let each = |f: fn(Sensor, f64) -> Vec<Case>| {
        [Sensor::Sleeve, Sensor::Grid10]
            .into_iter()
            .flat_map(move |s| RATES_HZ.into_iter().map(move |r| f(s, r)))
            .flatten()
    };
    each(cases_on).chain(each(real_like_on)).collect()
}
