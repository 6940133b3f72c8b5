//! Meta/Lofelt `.haptic` (data model version 1.0.0, the format of Meta Haptics Studio
//! and the Lofelt SDK), one signal per file.
//!
//! The format has no channels and no sign: a continuous signal's amplitude envelope,
//! breakpoints of `time` (seconds, non-decreasing) and `amplitude` (0..1). The envelope
//! here is the current mapped affinely onto 0..1 (`to_unit`: 0 pulled fully back, 1/2
//! no current, 1 fully pressed; the sleeve's rest is 0.05), on line segments within
//! `CURVE_TOLERANCE_FS` of the player's output. What is lost: which actuator it was
//! (one file per actuator, or the mix), and the meaning: a phone or controller plays
//! the amplitude as the strength of a vibration, not as an indentation.

use serde::Serialize;

use super::{from_unit, to_unit, ExportError, Pick, Playback, UnitScale, CURVE_TOLERANCE_FS};

#[derive(Serialize)]
struct DataModel<'a> {
    version: Version,
    metadata: MetaData,
    signals: Signals<'a>,
}

#[derive(Serialize)]
struct Version {
    major: u32,
    minor: u32,
    patch: u32,
}

#[derive(Serialize)]
struct MetaData {
    editor: String,
    author: String,
    source: String,
    project: String,
    tags: Vec<String>,
    description: String,
}

#[derive(Serialize)]
struct Signals<'a> {
    continuous: Continuous<'a>,
}

#[derive(Serialize)]
struct Continuous<'a> {
    envelopes: Envelopes<'a>,
}

#[derive(Serialize)]
struct Envelopes<'a> {
    amplitude: &'a [Breakpoint],
}

#[derive(Serialize)]
struct Breakpoint {
    time: f64,
    amplitude: f64,
}

/// The envelope: the current mapped onto 0..1 ([`to_unit`]); one unit of amplitude is
/// two of current, so half the tolerance.
pub(crate) const SCALE: UnitScale = UnitScale {
    tol: CURVE_TOLERANCE_FS / 2.0,
    to: to_unit,
    from: from_unit,
};

/// One `.haptic` file of the envelope `points` ([`SCALE`]) of the signal `pick` chose.
pub(crate) fn write(
    playback: &Playback,
    pick: Pick,
    points: &[(usize, f64)],
) -> Result<Vec<u8>, ExportError> {
    let amplitude: Vec<Breakpoint> = points
        .iter()
        .map(|&(t, a)| Breakpoint {
            time: t as f64 / 1000.0,
            amplitude: a,
        })
        .collect();
    let which = match pick {
        Pick::Channel(c) => format!("actuator {c}"),
        Pick::Mix => "the most pressed of the eight actuators at each moment".into(),
    };
    let doc = DataModel {
        version: Version {
            major: 1,
            minor: 0,
            patch: 0,
        },
        metadata: MetaData {
            editor: "touchc".into(),
            author: String::new(),
            source: playback.name.clone(),
            project: playback.layout.id().to_string(),
            tags: vec!["touch".into()],
            description: format!(
                "{}: {which}, amplitude = (current / {} A + 1) / 2",
                playback.name, playback.full_scale_a
            ),
        },
        signals: Signals {
            continuous: Continuous {
                envelopes: Envelopes {
                    amplitude: &amplitude,
                },
            },
        },
    };
    Ok(serde_json::to_vec(&doc)?)
}
