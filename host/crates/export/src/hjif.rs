//! MPEG-I Haptics interchange format (HJIF, ISO/IEC 23090-31), written and read back.
//!
//! Written with the fields the reference software's JSON loader requires (`version`,
//! `profile`, `level`, `date`, `description`, `timescale`, `avatars`, `perceptions`,
//! `syncs`; per perception `id`, `avatar_id`, `description`, `perception_modality`,
//! `channels`, `effect_library`; per channel `id`, `description`, `gain`,
//! `mixing_coefficient`, `body_part_mask`, `bands`; per band `band_type`, integer
//! frequency limits, `effects`; per effect `effect_type` and an integer `position`) and
//! its value rules (a version year of 2023 or later, profile `Main`, level 1: at most
//! 128 channels and 7 bands each, timescale at most 48000, avatar ids other than 0,
//! actuator targets inside the actuator resolution).
//!
//! One perception, modality `Pressure`: the sleeve's coils press the skin in and let it
//! out at under 4 Hz, a quasi-static indentation, which the standard's modalities class
//! as pressure (`Vibrotactile` is for what is felt as vibration, from tens of hertz up;
//! `Force`/kinesthetic for loads on joints and muscles). Eight channels, the sleeve's,
//! in channel order, each on the forearm of the body-part mask, at its grid place as an
//! actuator target (`X` the column along the arm, 0 nearest the elbow; `Y` the row) and
//! its position in mm in its description. Each channel has one `Curve` band of linear
//! curves (timescale 1000: positions are the player's 1 ms ticks) whose keyframes are
//! the current as a fraction of the full scale, signed, within `CURVE_TOLERANCE_FS`
//! of the player's output.

use serde::{Deserialize, Serialize};
use touch_protocol::CHANNELS;
use touchc_model::layout::Workspace;

use super::{
    fidelity, fit_polyline, polyline_at, round_to, ErrorSum, ExportError, ExportFile, Exported,
    Playback, CURVE_TOLERANCE_FS,
};

/// The standard's edition this writer follows.
pub const VERSION: &str = "2023";
/// Ticks per second of every position.
pub(crate) const TIMESCALE: u32 = 1000;
/// The body-part mask bit of the left forearm (the mask's bit 13).
pub(crate) const LEFT_FOREARM_MASK: u32 = 0x0000_2000;
/// A curve band's upper frequency limit, Hz: the reference encoder's curve band,
/// far above the sleeve's 4 Hz low-pass.
pub(crate) const CURVE_BAND_UPPER_HZ: i32 = 72;
/// The text before the layout's geometry hash in the description, read back on import.
const GEOMETRY_TAG: &str = "geometry 0x";

/// An HJIF document, as far as this writer fills it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Document {
    /// `YYYY` or `YYYY-N`.
    pub version: String,
    /// ISO 8601 date.
    pub date: String,
    /// Free text: the stimulus and its layout.
    pub description: String,
    /// `Main` or `Simple Parametric`.
    pub profile: String,
    /// 1 or 2.
    pub level: u8,
    /// Ticks per second.
    pub timescale: u32,
    /// The perceptions (one here).
    pub perceptions: Vec<Perception>,
    /// The avatars.
    pub avatars: Vec<Avatar>,
    /// Synchronisation points (none).
    pub syncs: Vec<serde_json::Value>,
}

/// A body representation that perceptions refer to.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Avatar {
    /// Not 0 (reserved).
    pub id: i32,
    /// Level of detail.
    pub lod: i32,
    /// `Vibration`, `Pressure`, `Temperature` or `Custom`.
    #[serde(rename = "type")]
    pub kind: String,
}

/// One perception: a modality and its channels.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Perception {
    /// Unique among perceptions.
    pub id: i32,
    /// An avatar's id, or 0.
    pub avatar_id: i32,
    /// Free text.
    pub description: String,
    /// The modality.
    pub perception_modality: String,
    /// Library effects (none).
    pub effect_library: Vec<serde_json::Value>,
    /// The devices the signals were made for.
    #[serde(default)]
    pub reference_devices: Vec<ReferenceDevice>,
    /// The channels.
    pub channels: Vec<Channel>,
}

/// The actuator a signal was made for.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct ReferenceDevice {
    /// Unique in the perception.
    pub id: i32,
    /// Free text.
    pub name: String,
    /// Where it is worn.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub body_part_mask: Option<u32>,
    /// Lowest frequency it renders, Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub minimum_frequency: Option<f64>,
    /// Highest frequency it renders, Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub maximum_frequency: Option<f64>,
    /// Mechanical resonance, Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resonance_frequency: Option<f64>,
    /// Largest amplitude, in the keyframes' unit (1: the full scale).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub maximum_amplitude: Option<f64>,
    /// Coil impedance, ohm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub impedance: Option<f64>,
    /// Largest current, amperes: the amplifier's full scale.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub maximum_current: Option<f64>,
    /// `LRA`, `VCA`, `ERM`, `Piezo` or `Unknown`.
    #[serde(rename = "type", skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
}

/// An integer vector (each component -128..=127).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
pub(crate) struct Vector {
    /// First component.
    #[serde(rename = "X")]
    pub x: i32,
    /// Second component.
    #[serde(rename = "Y")]
    pub y: i32,
    /// Third component.
    #[serde(rename = "Z")]
    pub z: i32,
}

/// One channel: one actuator's signal.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Channel {
    /// Unique in the perception; the sleeve's channel here.
    pub id: i32,
    /// Free text: row, column and position in mm.
    pub description: String,
    /// Gain applied to the signal.
    pub gain: f64,
    /// Weight when channels are mixed onto fewer actuators.
    pub mixing_coefficient: f64,
    /// Where on the body.
    pub body_part_mask: u32,
    /// The reference device's id.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_device_id: Option<i32>,
    /// Named body parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub body_part_target: Option<Vec<String>>,
    /// The grid the actuator targets are on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actuator_resolution: Option<Vector>,
    /// This channel's actuator(s) on that grid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actuator_target: Option<Vec<Vector>>,
    /// The signal's bands.
    pub bands: Vec<Band>,
}

/// A frequency band of a channel.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Band {
    /// `Curve`, `VectorialWave`, `WaveletWave` or `Transient`.
    pub band_type: String,
    /// For curve bands: how keyframes are joined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve_type: Option<String>,
    /// Hz.
    pub lower_frequency_limit: i32,
    /// Hz.
    pub upper_frequency_limit: i32,
    /// The effects.
    pub effects: Vec<Effect>,
}

/// An effect: keyframes from a position.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Effect {
    /// `Basis`, `Reference` or `Composite`.
    pub effect_type: String,
    /// Start, in timescale ticks.
    pub position: i64,
    /// The keyframes.
    #[serde(default)]
    pub keyframes: Vec<Keyframe>,
}

/// A point of a curve.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub(crate) struct Keyframe {
    /// From the effect's position, in timescale ticks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_position: Option<i64>,
    /// The value, -1..=1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub amplitude_modulation: Option<f64>,
}

/// Writes `playback` as one HJIF document, dated `date`, its reference device resonating
/// at `resonance_hz` when that is known.
pub(crate) fn export(
    playback: &Playback,
    date: &str,
    resonance_hz: Option<f64>,
) -> Result<Exported, ExportError> {
    let fs = playback.full_scale_a;
    let mut err = ErrorSum::default();
    let channels = playback
        .layout
        .workspaces()
        .iter()
        .enumerate()
        .map(|(c, w)| channel(c, w, keyframes(&playback.amps[c], fs, &mut err)))
        .collect();
    let doc = document(playback, date, resonance_hz, channels);
    let bytes = serde_json::to_vec(&doc)?;
    let e = err;
    Ok(Exported {
        files: vec![ExportFile {
            suffix: String::new(),
            bytes,
        }],
        fidelity: fidelity(&e, &e),
    })
}

/// One channel's current (`amps`, amperes at 1 kHz) as the keyframes of a linear curve
/// in fractions of the full scale `fs`, within [`CURVE_TOLERANCE_FS`]; adds the curve's
/// error at every tick to `err`.
fn keyframes(amps: &[f64], fs: f64, err: &mut ErrorSum) -> Vec<Keyframe> {
    let normalised: Vec<f64> = amps.iter().map(|a| a / fs).collect();
    let points: Vec<(usize, f64)> = fit_polyline(&normalised, CURVE_TOLERANCE_FS)
        .into_iter()
        .map(|(t, v)| (t, round_to(v.clamp(-1.0, 1.0), 6)))
        .collect();
    let mut hint = 0;
    for (t, v) in normalised.iter().enumerate() {
        err.add(polyline_at(&points, t, &mut hint) - v);
    }
    points
        .iter()
        .map(|&(t, v)| Keyframe {
            relative_position: Some(t as i64),
            amplitude_modulation: Some(v),
        })
        .collect()
}

/// Channel `c`, the actuator of workspace `w`, on the left forearm at its grid place,
/// with its `keyframes` as one curve band.
fn channel(c: usize, w: &Workspace, keyframes: Vec<Keyframe>) -> Channel {
    Channel {
        id: c as i32,
        description: format!(
            "actuator {c}: row {}, column {}, x {} mm along the arm from the elbow end, \
             y {} mm, radius {} mm",
            w.row, w.column, w.x_mm, w.y_mm, w.radius_mm
        ),
        gain: 1.0,
        mixing_coefficient: 1.0,
        body_part_mask: LEFT_FOREARM_MASK,
        reference_device_id: Some(REFERENCE_DEVICE_ID),
        body_part_target: Some(vec!["Forearm".into()]),
        actuator_resolution: Some(Vector { x: 4, y: 2, z: 1 }),
        actuator_target: Some(vec![Vector {
            x: w.column as i32,
            y: w.row as i32,
            z: 0,
        }]),
        bands: vec![Band {
            band_type: "Curve".into(),
            curve_type: Some("Linear".into()),
            lower_frequency_limit: 0,
            upper_frequency_limit: CURVE_BAND_UPPER_HZ,
            effects: vec![Effect {
                effect_type: "Basis".into(),
                position: 0,
                keyframes,
            }],
        }],
    }
}

/// The document around `channels`: the stimulus and its layout in the description, one
/// pressure perception on the sleeve's voice coils (resonance `resonance_hz` if given).
fn document(
    playback: &Playback,
    date: &str,
    resonance_hz: Option<f64>,
    channels: Vec<Channel>,
) -> Document {
    let fs = playback.full_scale_a;
    let layout = &playback.layout;
    let hash = layout.geometry_hash();
    Document {
        version: VERSION.into(),
        date: date.into(),
        description: format!(
            "touchc stimulus {:?} for the sleeve layout {:?} ({GEOMETRY_TAG}{hash:08x}): \
             each channel's current as a fraction of the {fs} A full scale, at 1 kHz",
            playback.name,
            layout.id()
        ),
        profile: "Main".into(),
        level: 1,
        timescale: TIMESCALE,
        perceptions: vec![Perception {
            id: 0,
            avatar_id: 1,
            description: "indentation by voice coils on the forearm (0-4 Hz)".into(),
            perception_modality: "Pressure".into(),
            effect_library: Vec::new(),
            reference_devices: vec![ReferenceDevice {
                id: REFERENCE_DEVICE_ID,
                name: "voice coil (Tectonic TEAX19C01-8) on an LM675T current amplifier, 1 A/V"
                    .into(),
                body_part_mask: Some(LEFT_FOREARM_MASK),
                minimum_frequency: Some(0.0),
                maximum_frequency: Some(500.0),
                resonance_frequency: resonance_hz,
                maximum_amplitude: Some(1.0),
                impedance: Some(8.0),
                maximum_current: Some(fs),
                kind: Some("VCA".into()),
            }],
            channels,
        }],
        avatars: vec![Avatar {
            id: 1,
            lod: 0,
            kind: "Pressure".into(),
        }],
        syncs: Vec::new(),
    }
}

/// An HJIF document read back: the eight channels' currents at 1 kHz.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// Per tick, the eight currents, amperes (fraction of the full scale times
    /// `full_scale_a`).
    pub signal: Vec<[f64; CHANNELS]>,
    /// The geometry hash the document names.
    pub layout_hash: u32,
}

/// The sleeve's one reference device. MPEG's JSON schema
/// (`MPEG_haptics.reference_device.schema.json`) numbers reference devices from 1,
/// where channels, perceptions and effects count from 0.
const REFERENCE_DEVICE_ID: i32 = 1;

fn invalid(reason: impl Into<String>) -> ExportError {
    ExportError::Invalid {
        format: "HJIF",
        reason: reason.into(),
    }
}

/// Reads an HJIF document written for the sleeve: one perception of eight channels
/// (ids 0 to 7) of linear curves at timescale 1000, at most `super::MAX_EXPORT_MS`
/// long, naming the layout's geometry in its description. `full_scale_a` is the
/// current of amplitude 1.
pub fn import(bytes: &[u8], full_scale_a: f64) -> Result<Imported, ExportError> {
    let doc: Document = serde_json::from_slice(bytes).map_err(|e| invalid(e.to_string()))?;
    if doc.timescale != TIMESCALE {
        return Err(invalid(format!(
            "timescale {} (only 1000, the player's tick, is read)",
            doc.timescale
        )));
    }
    let layout_hash = doc
        .description
        .find(GEOMETRY_TAG)
        .and_then(|at| {
            let hex = doc.description.get(at + GEOMETRY_TAG.len()..)?.get(..8)?;
            u32::from_str_radix(hex, 16).ok()
        })
        .ok_or_else(|| {
            invalid("its description names no sleeve layout geometry (`geometry 0x........`)")
        })?;
    let [perception] = doc.perceptions.as_slice() else {
        return Err(invalid(format!(
            "{} perceptions, expected one",
            doc.perceptions.len()
        )));
    };
    if perception.channels.len() != CHANNELS {
        return Err(invalid(format!(
            "{} channels, expected {CHANNELS}",
            perception.channels.len()
        )));
    }
    let mut curves: [Vec<(usize, f64)>; CHANNELS] = Default::default();
    for ch in &perception.channels {
        let c = usize::try_from(ch.id)
            .ok()
            .filter(|&c| c < CHANNELS && curves[c].is_empty())
            .ok_or_else(|| invalid(format!("channel id {} is not a free sleeve channel", ch.id)))?;
        let mut points = Vec::new();
        for band in &ch.bands {
            if band.band_type != "Curve"
                || band.curve_type.as_deref().unwrap_or("Linear") != "Linear"
            {
                return Err(invalid(format!(
                    "channel {c}: a {} band (only linear curves are read)",
                    band.band_type
                )));
            }
            for effect in &band.effects {
                for k in &effect.keyframes {
                    let (Some(rel), Some(a)) = (k.relative_position, k.amplitude_modulation) else {
                        continue;
                    };
                    let t = effect.position.checked_add(rel).filter(|t| *t >= 0);
                    let t = t
                        .and_then(|t| usize::try_from(t).ok())
                        .filter(|&t| t <= super::MAX_EXPORT_MS as usize)
                        .ok_or_else(|| {
                            invalid(format!(
                                "channel {c}: a keyframe at {rel} ms (from {} ms), outside \
                                 0 to {} ms",
                                effect.position,
                                super::MAX_EXPORT_MS
                            ))
                        })?;
                    if !a.is_finite() || a.abs() > 1.0 {
                        return Err(invalid(format!(
                            "channel {c}: amplitude {} outside -1..=1",
                            touchc_model::display::Shortest(a)
                        )));
                    }
                    points.push((t, a));
                }
            }
        }
        if points.is_empty() {
            return Err(invalid(format!("channel {c} has no keyframes")));
        }
        points.sort_by_key(|p| p.0);
        if points.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(invalid(format!(
                "channel {c}: two keyframes at one position"
            )));
        }
        curves[c] = points;
    }
    let ticks = curves
        .iter()
        .filter_map(|p| p.last().map(|l| l.0 + 1))
        .max()
        .unwrap_or(1);
    let mut hints = [0usize; CHANNELS];
    let signal = (0..ticks)
        .map(|t| std::array::from_fn(|c| polyline_at(&curves[c], t, &mut hints[c]) * full_scale_a))
        .collect();
    Ok(Imported {
        signal,
        layout_hash,
    })
}
