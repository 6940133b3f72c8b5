//! bHaptics `.tact` (the bHaptics Designer's export, read by the bHaptics SDKs), on the
//! six motors of one forearm device (Tactosy for arms: 3 along the arm x 2 across).
//!
//! The sleeve's 2 x 4 actuators are mapped onto the device by position. The device's
//! rows are the sleeve's rows; along the arm, each actuator's centre, as a fraction
//! `u` of the layout's extent (0 at the elbow end), feeds the motor columns at 0, 1/2
//! and 1 with the weight `max(0, 1 - |u - x| / (1/2))` (linear interpolation between
//! the two nearest motor columns), and a motor plays the weighted mean of the
//! amplitudes it is fed (the current mapped onto 0..1 as for `.haptic`,
//! `super::to_unit`: the sleeve's rest is 0.05, full press 1). On the paper's layout (u = 0, 1/3, 2/3, 1): the elbow motor
//! takes column 0 at weight 1 and column 1 at 1/3; the middle motor columns 1 and 2 at
//! 2/3 each; the wrist motor column 2 at 1/3 and column 3 at 1.
//!
//! Dot mode: frames of `FRAME_MS` ms (the SDKs' update interval), each motor at the
//! mean of its signal over the frame, in whole percent (the motors' 0-100 scale,
//! written as the designer does, 0..1), identical consecutive frames merged. Lost: two
//! of eight places (neighbours are averaged), detail under 20 ms and under 2% of
//! full scale (a whole percent of amplitude), and the meaning: the motors vibrate.

use serde::Serialize;
use touch_protocol::CHANNELS;

use super::{fidelity, from_unit, to_unit, ErrorSum, ExportError, ExportFile, Exported, Playback};

/// A frame's length, ms.
pub(crate) const FRAME_MS: usize = 20;
/// The device's motors.
pub(crate) const MOTORS: usize = 6;
/// Motor columns along the arm.
const MOTOR_COLUMNS: usize = 3;
/// The device's position name in the SDKs.
pub(crate) const POSITION: &str = "ForearmL";

/// Each motor's weight for each sleeve channel (rows: motors in index order: the first
/// row's three from the elbow end, then the second row's).
pub fn weights(playback: &Playback) -> [[f64; CHANNELS]; MOTORS] {
    let ws = playback.layout.workspaces();
    let (lo, hi) = ws
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
            (lo.min(w.x_mm), hi.max(w.x_mm))
        });
    let span = (hi - lo).max(f64::EPSILON);
    let mut out = [[0.0; CHANNELS]; MOTORS];
    for (m, row) in out.iter_mut().enumerate() {
        let (motor_row, motor_col) = (m / MOTOR_COLUMNS, m % MOTOR_COLUMNS);
        let x = motor_col as f64 / (MOTOR_COLUMNS - 1) as f64;
        for (c, w) in ws.iter().enumerate() {
            if w.row != motor_row {
                continue;
            }
            let u = (w.x_mm - lo) / span;
            row[c] = (1.0 - (u - x).abs() * (MOTOR_COLUMNS - 1) as f64).max(0.0);
        }
    }
    out
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct File {
    project: Project,
    duration_millis: usize,
    interval_millis: usize,
    size: usize,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Project {
    name: String,
    description: String,
    media_file_duration: f64,
    layout: Layout,
    tracks: Vec<Track>,
}

#[derive(Serialize)]
struct Layout {
    name: &'static str,
    #[serde(rename = "type")]
    kind: &'static str,
    layouts: std::collections::BTreeMap<&'static str, Vec<Motor>>,
}

#[derive(Serialize)]
struct Motor {
    index: usize,
    x: f64,
    y: f64,
}

#[derive(Serialize)]
struct Track {
    enable: bool,
    effects: Vec<Effect>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Effect {
    name: String,
    start_time: usize,
    offset_time: usize,
    modes: std::collections::BTreeMap<&'static str, Mode>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Mode {
    mode: &'static str,
    dot_mode: DotMode,
    path_mode: PathMode,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct DotMode {
    dot_connected: bool,
    feedback: Vec<DotFeedback>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct DotFeedback {
    start_time: usize,
    end_time: usize,
    playback_type: &'static str,
    point_list: Vec<Point>,
}

#[derive(Serialize)]
struct Point {
    index: usize,
    intensity: f64,
}

#[derive(Serialize)]
struct PathMode {
    feedback: Vec<serde_json::Value>,
}

/// The six motors' percentages, frame by frame, and the reconstruction's errors.
pub(crate) fn frames(playback: &Playback) -> (Vec<[u8; MOTORS]>, ErrorSum, ErrorSum) {
    let fs = playback.full_scale_a;
    let weights = weights(playback);
    let ticks = playback.ticks();
    let motor_at = |m: usize, t: usize| {
        let (num, den) = (0..CHANNELS).fold((0.0, 0.0), |(n, d), c| {
            (
                n + weights[m][c] * to_unit(playback.amps[c][t], fs),
                d + weights[m][c],
            )
        });
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    };
    let mut frames = Vec::new();
    let (mut err, mut fit) = (ErrorSum::default(), ErrorSum::default());
    for start in (0..ticks).step_by(FRAME_MS) {
        let end = (start + FRAME_MS).min(ticks);
        let frame: [u8; MOTORS] = std::array::from_fn(|m| {
            let mean = (start..end).map(|t| motor_at(m, t)).sum::<f64>() / (end - start) as f64;
            (mean * 100.0).round().clamp(0.0, 100.0) as u8
        });
        for t in start..end {
            for (m, &pct) in frame.iter().enumerate() {
                // In current, as every other figure: one unit of amplitude is two.
                fit.add(2.0 * (f64::from(pct) / 100.0 - motor_at(m, t)));
            }
            // What each actuator's place gets back from the motors around it.
            for (c, amps) in playback.amps.iter().enumerate() {
                let (num, den) = (0..MOTORS).fold((0.0, 0.0), |(n, d), m| {
                    (
                        n + weights[m][c] * f64::from(frame[m]) / 100.0,
                        d + weights[m][c],
                    )
                });
                let back = if den > 0.0 { num / den } else { 0.0 };
                err.add((from_unit(back, fs) - amps[t]) / fs);
            }
        }
        frames.push(frame);
    }
    (frames, err, fit)
}

/// Writes `playback` as one `.tact` file for the left forearm's device.
pub fn export(playback: &Playback) -> Result<Exported, ExportError> {
    let (frames, err, fit) = frames(playback);
    let duration = playback.ticks();
    let mut feedback: Vec<DotFeedback> = Vec::new();
    let mut previous: Option<[u8; MOTORS]> = None;
    for (k, frame) in frames.iter().enumerate() {
        let start = k * FRAME_MS;
        let end = (start + FRAME_MS).min(duration);
        if previous == Some(*frame) {
            if let Some(last) = feedback.last_mut() {
                last.end_time = end;
            }
            continue;
        }
        previous = Some(*frame);
        if frame.iter().all(|&p| p == 0) {
            continue;
        }
        feedback.push(DotFeedback {
            start_time: start,
            end_time: end,
            playback_type: "NONE",
            point_list: frame
                .iter()
                .enumerate()
                .filter(|(_, &p)| p > 0)
                .map(|(index, &p)| Point {
                    index,
                    intensity: f64::from(p) / 100.0,
                })
                .collect(),
        });
    }
    let motors = (0..MOTORS)
        .map(|m| Motor {
            index: m,
            x: (m % MOTOR_COLUMNS) as f64 / (MOTOR_COLUMNS - 1) as f64,
            y: (m / MOTOR_COLUMNS) as f64,
        })
        .collect();
    let file = File {
        project: Project {
            name: playback.name.clone(),
            description: format!(
                "touchc stimulus {:?} ({}), the 2 x 4 sleeve mapped onto 3 x 2 motors by \
                 position, motor column 0 at the elbow",
                playback.name,
                playback.layout.id()
            ),
            media_file_duration: duration as f64 / 1000.0,
            layout: Layout {
                name: "Tactosy",
                kind: "Tactosy_arms",
                layouts: [(POSITION, motors)].into_iter().collect(),
            },
            tracks: vec![Track {
                enable: true,
                effects: vec![Effect {
                    name: playback.name.clone(),
                    start_time: 0,
                    offset_time: duration,
                    modes: [(
                        POSITION,
                        Mode {
                            mode: "DOT_MODE",
                            dot_mode: DotMode {
                                dot_connected: false,
                                feedback,
                            },
                            path_mode: PathMode {
                                feedback: Vec::new(),
                            },
                        },
                    )]
                    .into_iter()
                    .collect(),
                }],
            }],
        },
        duration_millis: duration,
        interval_millis: FRAME_MS,
        size: frames.len(),
    };
    Ok(Exported {
        files: vec![ExportFile {
            suffix: String::new(),
            bytes: serde_json::to_vec(&file)?,
        }],
        fidelity: fidelity(&err, &fit),
    })
}
