//! Real touch, measured: every case of issue 12 on both sensors, under each preset,
//! against the truth of where each contact was (`touchc::measure::evaluate`).

use touchc::compile::{compile, CompileOptions, Compiled};
use touchc::config::{Config, MetadataOverrides, Preset};
use touchc::input::recording::Recording;
use touchc::input::synth::{self, Gesture, Sensor, SynthSpec, Tuning};
use touchc::measure::evaluate::{evaluate_compiled, Evaluation};
use touchc::rendering::signals::Source;

/// One synthetic case: a name and its spec on `sensor`.
struct Case {
    name: String,
    spec: SynthSpec,
}

fn spec(sensor: Sensor, gestures: &[Gesture], tuning: Tuning) -> SynthSpec {
    SynthSpec {
        gestures: gestures.to_vec(),
        seed: 1,
        noise_psi: 0.003,
        // 1.5 s of quiet on each side: more than any tare window.
        quiet_frames: (sensor.rate_hz() * 1.5).round() as usize,
        sensor,
        tuning,
        ..SynthSpec::default()
    }
}

fn cases(sensor: Sensor) -> Vec<Case> {
    let mut out = Vec::new();
    let mut add = |name: String, spec: SynthSpec| out.push(Case { name, spec });
    for v in [0.05, 0.3, 1.0, 1.5] {
        let t = Tuning {
            stroke_speed_mps: Some(v),
            ..Tuning::default()
        };
        add(
            format!("stroke {v} m/s"),
            spec(sensor, &[Gesture::Stroke], t),
        );
    }
    for ms in [50.0, 100.0] {
        let t = Tuning {
            tap_s: Some(ms / 1000.0),
            ..Tuning::default()
        };
        add(format!("taps {ms} ms"), spec(sensor, &[Gesture::Tap], t));
    }
    add(
        "palm".into(),
        spec(sensor, &[Gesture::Palm], Tuning::default()),
    );
    for hz in [2.0, 4.0] {
        let t = Tuning {
            shake_hz: Some(hz),
            shake_amplitude_mm: Some(40.0),
            ..Tuning::default()
        };
        add(
            format!("shake {hz} Hz 40 mm"),
            spec(sensor, &[Gesture::Shake], t),
        );
    }
    let t = Tuning {
        gap_s: Some(0.15),
        ..Tuning::default()
    };
    add(
        "strokes 150 ms apart".into(),
        spec(sensor, &[Gesture::Strokes], t),
    );
    add(
        "begins mid-touch (palm, stroke)".into(),
        SynthSpec {
            begin_mid_touch: true,
            ..spec(sensor, &[Gesture::Palm, Gesture::Stroke], Tuning::default())
        },
    );
    add(
        "ends mid-touch (stroke, palm)".into(),
        SynthSpec {
            end_mid_touch: true,
            ..spec(sensor, &[Gesture::Stroke, Gesture::Palm], Tuning::default())
        },
    );
    add(
        "flicker (strokes, palm)".into(),
        SynthSpec {
            flicker: 5.0,
            ..spec(
                sensor,
                &[Gesture::Strokes, Gesture::Palm],
                Tuning::default(),
            )
        },
    );
    add(
        "noise only".into(),
        spec(sensor, &[Gesture::Rest], Tuning::default()),
    );
    out
}

/// Compiles `case` under `preset` at the sensor's rate and pitch, and measures it.
fn run(case: &Case, preset: Preset, seed: u64) -> (Evaluation, Compiled) {
    let spec = SynthSpec {
        seed,
        ..case.spec.clone()
    };
    let (data, truth) = synth::generate_with_truth(&spec);
    let rec = Recording::from_array(case.name.clone(), data.view()).unwrap();
    let compiled = compile(
        &rec,
        &CompileOptions {
            config: Config::preset(preset),
            metadata: MetadataOverrides {
                rate_hz: Some(truth.rate_hz),
                pitch_mm: Some(truth.pitch_mm),
            },
            ..CompileOptions::default()
        },
    )
    .unwrap();
    let e = evaluate_compiled(&truth, &rec, &compiled).unwrap();
    (e, compiled)
}

/// Of the frames and actuators a flat hand covers (the actuator's centre well inside
/// the contact, under half its radius from its centre), the share that render.
fn covered_rendered(case: &Case, compiled: &Compiled, offset: usize) -> Option<f64> {
    let (_, truth) = synth::generate_with_truth(&case.spec);
    let placement = compiled.placement.as_ref()?;
    let signals = compiled.signals.as_ref()?;
    let (mut covered, mut rendered) = (0usize, 0usize);
    for c in truth.contacts.iter().filter(|c| c.gesture == Gesture::Palm) {
        for p in c.points.iter().filter(|p| p.pressure_psi > 0.2) {
            let Some(f) = p.frame.checked_sub(offset) else {
                continue;
            };
            for (ch, circle) in placement.circles.iter().enumerate() {
                let d = ((circle.x_mm - p.x_mm).powi(2) + (circle.y_mm - p.y_mm).powi(2)).sqrt();
                if d < 0.5 * p.radius_mm && f < signals.frames() {
                    covered += 1;
                    rendered += usize::from(signals.source[ch][f] != Source::Silent);
                }
            }
        }
    }
    (covered > 0).then(|| rendered as f64 / covered as f64)
}

/// The bar for the default preset: recall >= 0.95, coverage >= 0.9, no merges,
/// no false contacts, on every case, both sensors, two seeds; `paper` printed beside.
#[test]
fn the_default_renders_every_case_on_both_sensors() {
    assert_eq!(Config::default(), Config::preset(Preset::Touch));
    let mut failures = Vec::new();
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for case in cases(sensor) {
            for seed in [1, 2] {
                let (e, c) = run(&case, Preset::Touch, seed);
                let palm = covered_rendered(&case, &c, 0);
                let (paper, _) = run(&case, Preset::Paper, seed);
                eprintln!(
                    "{:7} {:32} seed {seed}  touch: {}{}  | paper: {}",
                    sensor.name(),
                    case.name,
                    e.summary(),
                    palm.map_or(String::new(), |v| format!(", palm rendered {v:.2}")),
                    paper.summary()
                );
                let ok = e.recall() >= 0.95
                    && e.coverage.ratio() >= 0.9
                    && e.merges == 0
                    && e.false_contacts == 0
                    && palm.is_none_or(|v| v >= 0.9);
                if !ok {
                    failures.push(format!(
                        "{} {} seed {seed}: {}",
                        sensor.name(),
                        case.name,
                        e.summary()
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
