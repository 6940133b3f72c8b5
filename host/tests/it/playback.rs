//! What the sleeve plays of the shipped examples, checked outside the encoder: each
//! stimulus is decoded from its bytes, played by the protocol's real `Player` on the
//! sleeve's device, each code turned into amperes by `code_to_amps`, and the RMS and
//! largest error against the compiler's conditioned 1 kHz signal summed here. The
//! encoder's own measurement (and the report it writes) is what is under test: the
//! figures recomputed here must meet the configured bounds and equal the report's.

use std::path::{Path, PathBuf};

use touch_protocol::player::code_to_amps;
use touch_protocol::{DeviceConfig, Player, Status, Stimulus, CHANNELS};
use touchc_input::recording::Recording;
use touchc_model::config::{Config, Preset};
use touchc_pipeline::compile::{compile, CompileOptions, Compiled};

/// The errors of `bytes` played on the sleeve against `signal` (amperes at 1 kHz), as
/// fractions of the full scale: over every tick until the player is finished and the
/// signal is over (after its end the signal is 0 A), every channel.
fn played_errors(bytes: &[u8], signal: &[[f64; CHANNELS]]) -> (f64, f64) {
    let s = Stimulus::decode(bytes).expect("the written stimulus decodes");
    let device = DeviceConfig::default();
    assert_eq!(
        s.header().full_scale_ma,
        device.full_scale_ma,
        "compiled for the sleeve's scale"
    );
    let fs_a = f64::from(device.full_scale_ma) / 1000.0;
    let mut player = Player::new(&s, &device);
    let (mut sum2, mut max, mut samples) = (0.0f64, 0.0f64, 0usize);
    for t in 0usize.. {
        let tick = player.tick();
        assert!(
            !matches!(tick.status, Status::Fault(_)),
            "{}: a limit is hit at tick {t}: {:?}",
            s.name(),
            tick.status
        );
        let want = signal.get(t).copied().unwrap_or([0.0; CHANNELS]);
        for (&code, want) in tick.codes.iter().zip(want) {
            let e = (code_to_amps(code, device.full_scale_ma) - want).abs() / fs_a;
            sum2 += e * e;
            max = max.max(e);
            samples += 1;
        }
        if tick.status == Status::Finished && t + 1 >= signal.len() {
            break;
        }
    }
    ((sum2 / samples as f64).sqrt(), max)
}

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

fn compiled(npy: &Path, config: Config, name: &str) -> Compiled {
    let rec = Recording::load(npy).unwrap_or_else(|e| panic!("{}: {e}", npy.display()));
    compile(
        &rec,
        &CompileOptions {
            config: config.validated().unwrap(),
            name: name.into(),
            ..CompileOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", npy.display()))
}

/// The played errors meet the configured bounds, and the report says what they are.
fn check(what: &str, c: &Compiled, config: &Config) -> (f64, f64) {
    let (rms, max) = played_errors(&c.stimulus, &c.signal);
    let k = &config.keyframes;
    eprintln!(
        "{what}: played RMS {:.4} % FS (report {:.4} %), max {:.4} % FS (report {:.4} %)",
        100.0 * rms,
        100.0 * c.report.rms_error_fs,
        100.0 * max,
        100.0 * c.report.max_error_fs
    );
    assert!(
        rms <= k.max_rms_error_fs,
        "{what}: RMS {rms} over {}",
        k.max_rms_error_fs
    );
    assert!(
        max <= k.max_abs_error_fs,
        "{what}: max {max} over {}",
        k.max_abs_error_fs
    );
    // The report is the encoder's own sum; the same quantities in another order.
    assert!(
        (rms - c.report.rms_error_fs).abs() <= 1e-9,
        "{what}: played RMS {rms}, the report says {}",
        c.report.rms_error_fs
    );
    assert!(
        (max - c.report.max_error_fs).abs() <= 1e-12,
        "{what}: played max {max}, the report says {}",
        c.report.max_error_fs
    );
    (rms, max)
}

/// The emoji bank's stimuli, as committed: compiled again from their recordings with
/// the flags `examples/emoji/build.sh` uses, they are the committed bytes, and their
/// playback meets the bounds.
#[test]
fn the_emoji_stimuli_play_within_the_error_bounds() {
    let emoji = examples().join("emoji");
    for name in [
        "attention",
        "gratitude",
        "happiness",
        "calming",
        "love",
        "sadness",
    ] {
        let config = Config::preset(Preset::Paper);
        let c = compiled(&emoji.join(format!("{name}.npy")), config.clone(), name);
        let committed = std::fs::read(emoji.join(format!("{name}.touch"))).unwrap();
        assert!(
            c.stimulus == committed,
            "examples/emoji/{name}.touch is not what its recording compiles to"
        );
        check(name, &c, &config);
    }
}

/// The top-level examples, compiled with the defaults, play within the bounds.
#[test]
fn the_examples_play_within_the_error_bounds() {
    for name in ["tap_pat", "stroke", "squeeze", "combination"] {
        let config = Config::default();
        let c = compiled(
            &examples().join(format!("{name}.npy")),
            config.clone(),
            name,
        );
        check(name, &c, &config);
    }
}
