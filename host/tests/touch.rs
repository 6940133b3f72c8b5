//! Real touch, measured: every case of issue 12 on both sensors, under each preset,
//! against the truth of where each contact was (`touchc::evaluate`).

use touchc::compile::{compile, CompileOptions, Compiled};
use touchc::config::Config;
use touchc::evaluate::{evaluate, Evaluation};
use touchc::recording::Recording;
use touchc::synth::{self, Gesture, Sensor, SynthSpec, Tuning};

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
        add(format!("stroke {v} m/s"), spec(sensor, &[Gesture::Stroke], t));
    }
    for ms in [50.0, 100.0] {
        let t = Tuning {
            tap_s: Some(ms / 1000.0),
            ..Tuning::default()
        };
        add(format!("taps {ms} ms"), spec(sensor, &[Gesture::Tap], t));
    }
    add("palm".into(), spec(sensor, &[Gesture::Palm], Tuning::default()));
    for hz in [2.0, 4.0] {
        let t = Tuning {
            shake_hz: Some(hz),
            shake_amplitude_mm: Some(40.0),
            ..Tuning::default()
        };
        add(format!("shake {hz} Hz 40 mm"), spec(sensor, &[Gesture::Shake], t));
    }
    let t = Tuning {
        gap_s: Some(0.15),
        ..Tuning::default()
    };
    add("strokes 150 ms apart".into(), spec(sensor, &[Gesture::Strokes], t));
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
            flicker: 0.1,
            ..spec(sensor, &[Gesture::Strokes, Gesture::Palm], Tuning::default())
        },
    );
    add("noise only".into(), spec(sensor, &[Gesture::Rest], Tuning::default()));
    out
}

fn run(case: &Case, cfg: &Config) -> (Evaluation, Compiled) {
    let (data, truth) = synth::generate_with_truth(&case.spec);
    let rec = Recording::from_array(case.name.clone(), data.view()).unwrap();
    let compiled = compile(
        &rec,
        &CompileOptions {
            config: cfg.clone(),
            ..CompileOptions::default()
        },
    )
    .unwrap();
    let tared = rec.tare(&cfg.input).unwrap();
    let trajectories = compiled
        .tracked
        .as_ref()
        .map_or(&[][..], |t| &t.trajectories[..]);
    let e = evaluate(
        &truth,
        cfg.input.tare_frames,
        tared.view(),
        cfg.input.touch_threshold_psi,
        trajectories,
        cfg.preprocess.upsample,
    );
    (e, compiled)
}

fn at_rate(mut cfg: Config, sensor: Sensor) -> Config {
    let rate = sensor.rate_hz();
    cfg.input.frame_rate_hz = rate;
    cfg.input.tare_frames = (rate * 1.0).round() as usize;
    cfg
}

#[test]
fn measure() {
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for case in cases(sensor) {
            let (e, _) = run(&case, &at_rate(Config::default(), sensor));
            eprintln!("{:7} {:32} paper: {}", sensor.name(), case.name, e.summary());
        }
    }
}
