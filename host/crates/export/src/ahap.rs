//! Apple Haptic and Audio Pattern (AHAP, Core Haptics), one signal per file.
//!
//! `Version` 1.0; `HapticContinuous` events of intensity 1 and sharpness 0 (a dull,
//! pressing feel) back to back, each at most `MAX_EVENT_S` long (Core Haptics'
//! limit for a continuous event), under an intensity control curve
//! (`HapticIntensityControl`) chained in `ParameterCurve`s of at most
//! `MAX_CONTROL_POINTS` points (Core Haptics' limit per curve), each curve starting
//! at the previous one's last point, control point times relative to their curve's.
//!
//! Core Haptics' intensity is perceptual, not a current: as Lofelt's converter does,
//! intensity is the square root of the amplitude, here the current mapped onto 0..1
//! as for `.haptic` (`super::to_unit`: the sleeve's rest is 0.05, no current 1/2,
//! full press 1), so the reconstructed amplitude is the intensity squared. Lost: which
//! actuator (one file per actuator, or the mix), and the meaning: an iPhone plays the
//! intensity as the strength of a vibration, not as an indentation.

use serde::Serialize;

use super::{from_unit, round_to, to_unit, ExportError, Pick, Playback, UnitScale};

/// Core Haptics' limit on a `HapticContinuous` event's duration, seconds.
pub(crate) const MAX_EVENT_S: f64 = 30.0;
/// Core Haptics' limit on the control points of one parameter curve.
pub(crate) const MAX_CONTROL_POINTS: usize = 16;
/// Tolerance of the intensity curve: a quarter of the other formats' (an intensity
/// error `e` is an amplitude error of at most `2 e`, and one unit of amplitude is two
/// of current).
const INTENSITY_TOLERANCE: f64 = super::CURVE_TOLERANCE_FS / 4.0;

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Ahap {
    version: f64,
    metadata: MetaData,
    pattern: Vec<Pattern>,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct MetaData {
    project: String,
    created: String,
    description: String,
}

#[derive(Serialize)]
enum Pattern {
    Event(Event),
    ParameterCurve(ParameterCurve),
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Event {
    time: f64,
    event_type: &'static str,
    event_duration: f64,
    event_parameters: Vec<Parameter>,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Parameter {
    #[serde(rename = "ParameterID")]
    parameter_id: &'static str,
    parameter_value: f64,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct ParameterCurve {
    #[serde(rename = "ParameterID")]
    parameter_id: &'static str,
    time: f64,
    parameter_curve_control_points: Vec<ControlPoint>,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct ControlPoint {
    time: f64,
    parameter_value: f64,
}

/// The intensity: the square root of the current mapped onto 0..1 ([`to_unit`]), so
/// the reader's amplitude is the intensity squared.
pub(crate) const SCALE: UnitScale = UnitScale {
    tol: INTENSITY_TOLERANCE,
    to: |a, fs| to_unit(a, fs).sqrt(),
    from: |i, fs| from_unit(i * i, fs),
};

/// One AHAP file of the intensity `points` ([`SCALE`]) of the signal `pick` chose.
pub(crate) fn write(
    playback: &Playback,
    pick: Pick,
    points: &[(usize, f64)],
) -> Result<Vec<u8>, ExportError> {
    let fs = playback.full_scale_a;
    let seconds = |t: usize| t as f64 / 1000.0;
    let total = seconds(points.last().map_or(0, |p| p.0));
    let mut pattern = Vec::new();
    let mut start = 0.0;
    while start < total {
        let duration = (total - start).min(MAX_EVENT_S);
        pattern.push(Pattern::Event(Event {
            time: round_to(start, 3),
            event_type: "HapticContinuous",
            event_duration: round_to(duration, 3),
            event_parameters: vec![
                Parameter {
                    parameter_id: "HapticIntensity",
                    parameter_value: 1.0,
                },
                Parameter {
                    parameter_id: "HapticSharpness",
                    parameter_value: 0.0,
                },
            ],
        }));
        start += duration;
    }
    // Each curve holds its first point (the last of the one before) and up to 15 more.
    let mut first = 0;
    while first + 1 < points.len() {
        let last = (first + MAX_CONTROL_POINTS - 1).min(points.len() - 1);
        let t0 = points[first].0;
        pattern.push(Pattern::ParameterCurve(ParameterCurve {
            parameter_id: "HapticIntensityControl",
            time: seconds(t0),
            parameter_curve_control_points: points[first..=last]
                .iter()
                .map(|&(t, v)| ControlPoint {
                    time: seconds(t - t0),
                    parameter_value: v,
                })
                .collect(),
        }));
        first = last;
    }
    let which = match pick {
        Pick::Channel(c) => format!("actuator {c}"),
        Pick::Mix => "the most pressed of the eight actuators at each moment".into(),
    };
    let doc = Ahap {
        version: 1.0,
        metadata: MetaData {
            project: "touchc".into(),
            created: String::new(),
            description: format!(
                "{} on {}: {which}, intensity = sqrt((current / {fs} A + 1) / 2)",
                playback.name,
                playback.layout.id()
            ),
        },
        pattern,
    };
    Ok(serde_json::to_vec(&doc)?)
}
