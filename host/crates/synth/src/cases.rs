//! The synthetic cases of real touch that tracking is measured on (`touchc trade
//! --cases`, `docs/trade.md`): what captures of other sensors hold and the paper's
//! scenes do not (a flat hand with a weaker heel, rubs up to a vigorous 1 m/s, many
//! strokes in quick succession, fast swipes), each on both sensors and at both rates.

use super::{Gesture, Sensor, SynthSpec, Tuning};

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

/// Every case on both sensors at both rates ([`RATES_HZ`]).
pub fn cases() -> Vec<Case> {
    [Sensor::Sleeve, Sensor::Grid10]
        .into_iter()
        .flat_map(|s| RATES_HZ.into_iter().map(move |r| cases_on(s, r)))
        .flatten()
        .collect()
}
