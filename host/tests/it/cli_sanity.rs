//! The real binary on recordings that compile but look wrong (warnings, exit 0, output
//! written), on knobs that must be refused (exit 1, nothing written), on a recording
//! that begins mid-press, and on one touch sampled at two rates.

use crate::bin::{s, touchc};
use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use ndarray::Array3;

fn write(dir: &Path, name: &str, rec: &Array3<f64>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, touchc_synth::to_npy(rec).unwrap()).unwrap();
    path
}

/// `frames` x 8 x 21 at `rest` with +-0.004 noise, NaN outside the 142-cell sleeve.
fn quiet(frames: usize, rest: f64, seed: u64) -> Array3<f64> {
    let mut noise = common::Xorshift::mixed(seed);
    Array3::from_shape_fn((frames, 8, 21), |(_, r, c)| {
        if common::sleeve_mask(r, c) {
            rest + 0.004 * noise.signed()
        } else {
            f64::NAN
        }
    })
}

/// Adds a 2 x 2-cell contact of `psi` at `(row, col)` (a soft edge on the neighbours).
fn press(a: &mut Array3<f64>, t: usize, row: f64, col: f64, psi: f64) {
    for r in 0..8 {
        for c in 0..21 {
            let d2 = (r as f64 - row).powi(2) + (c as f64 - col).powi(2);
            a[[t, r, c]] += psi * (-d2 / 1.5).exp();
        }
    }
}

/// Compiles `rec` with `extra` arguments: (exit status, stderr, stimulus written, report).
fn compile(rec: &Path, extra: &[&str]) -> (Output, String, bool, Option<serde_json::Value>) {
    let out_path = rec.with_extension("touch");
    let report_path = rec.with_extension("json");
    let mut args = vec![
        "compile",
        s(rec),
        "-o",
        s(&out_path),
        "--report",
        s(&report_path),
    ];
    args.extend_from_slice(extra);
    let out = touchc(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let report = std::fs::read_to_string(&report_path)
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    let written = out_path.exists();
    (out, err, written, report)
}

/// Exit 0, the stimulus written, and a warning on stderr containing every one of `want`.
fn warns(rec: &Path, extra: &[&str], want: &[&str]) {
    let (out, err, written, _) = compile(rec, extra);
    assert!(out.status.success(), "{}: {err}", out.status);
    assert!(written, "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("warning") && want.iter().all(|w| l.contains(w)));
    assert!(line.is_some(), "no warning with {want:?} in:\n{err}");
}

#[test]
fn shipped_examples_get_no_sanity_warning() {
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    for name in ["stroke", "tap_pat", "squeeze"] {
        let rec = dir.path().join(format!("{name}.npy"));
        std::fs::copy(examples.join(format!("{name}.npy")), &rec).unwrap();
        let (out, err, written, _) = compile(&rec, &[]);
        assert!(
            out.status.success() && written,
            "{name}: {}: {err}",
            out.status
        );
        assert!(!err.contains("warning"), "{name}: {err}");
    }
}

#[test]
fn raw_counts_warn_with_the_median() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = quiet(100, 512.0, 1);
    for t in 40..60 {
        press(&mut a, t, 3.5, 8.0 + (t - 40) as f64 * 0.2, 80.0);
    }
    let rec = write(dir.path(), "counts.npy", &a);
    warns(&rec, &[], &["median reading is 512", "raw ADC counts"]);
}

#[test]
fn falling_pressure_warns() {
    // 10-bit counts near 1020 at rest that fall under the press (REAL-TOUCH.md's kind).
    let dir = tempfile::tempdir().unwrap();
    let mut a = quiet(100, 1020.0, 2);
    for t in 40..60 {
        press(&mut a, t, 3.5, 8.0, -300.0);
    }
    let rec = write(dir.path(), "falling.npy", &a);
    warns(&rec, &[], &["fall with touch", "touch is positive psi"]);
}

/// 8 s at 20 Hz: a press held from the first frame to 2.5 s near the elbow, and a
/// stroke along the arm from 4.5 s to 6.5 s.
fn mid_press() -> Array3<f64> {
    let mut a = quiet(160, 0.0, 3);
    for t in 0..50 {
        press(&mut a, t, 3.5, 15.0, 2.0);
    }
    for t in 90..130 {
        press(&mut a, t, 3.5, 14.0 - (t - 90) as f64 * 0.2, 1.5);
    }
    a
}

/// Rows of `touchc render --csv`: `[t_s, ch0 .. ch7]`.
fn render(stimulus: &Path) -> Vec<Vec<f64>> {
    let csv = stimulus.with_extension("csv");
    let out = touchc(&["render", s(stimulus), "--csv", "-o", s(&csv)]);
    assert!(out.status.success());
    std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// The strongest current any channel reaches in the stimulus's first second, after the
/// 0.5 s ramp from 0 A to the pre-dent, A.
fn first_second_peak(rows: &[Vec<f64>]) -> f64 {
    rows.iter()
        .filter(|r| (0.6..1.0).contains(&r[0]))
        .flat_map(|r| r[1..].iter().copied())
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn a_recording_that_starts_mid_press_keeps_it_with_the_robust_baseline() {
    let dir = tempfile::tempdir().unwrap();
    // The paper's leading baseline: the press is tared away, and that is said.
    let leading = write(dir.path(), "leading.npy", &mid_press());
    warns(
        &leading,
        &["--preset", "paper"],
        &["touch in the tare window", "input.baseline=robust"],
    );
    let lost = first_second_peak(&render(&leading.with_extension("touch")));
    // The default preset's robust baseline: the press drives an actuator from the
    // start, no warning.
    let robust = write(dir.path(), "robust.npy", &mid_press());
    let (out, err, written, _) = compile(&robust, &[]);
    assert!(out.status.success() && written, "{}: {err}", out.status);
    assert!(!err.contains("tare window"), "{err}");
    let kept = first_second_peak(&render(&robust.with_extension("touch")));
    // The pre-dent is -0.9 A and the strongest pressure 1 A: the press lifts a channel
    // far above the pre-dent within the first second (after the 0.5 s ramp), the
    // leading baseline leaves every channel at it.
    assert!(kept > 0.0, "robust: {kept} A");
    assert!(lost < -0.85, "leading: {lost} A");
}

#[test]
fn a_rate_too_high_for_the_touch_warns() {
    // A contact sweeping one cell per frame: 0.5 m/s at 20 Hz, 5.1 m/s at 200 Hz. The
    // folder's name ends in "m", so every path the compile line names holds "m/s".
    let dir = tempfile::Builder::new().suffix("m").tempdir().unwrap();
    let mut a = quiet(100, 0.0, 4);
    for t in 30..70 {
        press(&mut a, t, 3.5, 2.0 + ((t - 30) % 17) as f64, 2.0);
    }
    let rec = write(dir.path(), "sweep.npy", &a);
    let short = ["--set", "input.tare_s=0.1", "--set", "input.trim_s=0.1"];
    let (out, err, _, _) = compile(&rec, &short);
    let speed_warning = err
        .lines()
        .any(|l| l.contains("warning") && l.contains("m/s"));
    assert!(
        out.status.success() && !speed_warning,
        "{}: {err}",
        out.status
    );
    let mut at_200 = short.to_vec();
    at_200.extend(["--rate", "200"]);
    warns(&rec, &at_200, &["median 5.1 m/s at 200 Hz", "--rate"]);
}

#[test]
fn single_frame_touches_warn() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = quiet(100, 0.0, 5);
    for t in [30, 40, 50, 60, 70] {
        press(&mut a, t, 3.5, 10.0, 2.0);
    }
    let rec = write(dir.path(), "blips.npy", &a);
    warns(
        &rec,
        &[],
        &["all 5 touches last a single frame", "50 ms at 20 Hz"],
    );
}

/// Each knob that used to hang, allocate gigabytes or panic is refused with its name,
/// the value and the range, as a usage error (exit 2), nothing written.
#[test]
fn knobs_out_of_range_are_refused_by_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let rec = write(dir.path(), "blobs.npy", &common::moving_blobs(100, 1, 6));
    for (set, want) in [
        (
            "preprocess.blur_sigma_mm=0",
            ["preprocess.blur_sigma_mm = 0", "[0.01, 500] mm"],
        ),
        (
            "preprocess.blur_truncate=0",
            ["preprocess.blur_truncate = 0", "[1, 10] sigmas"],
        ),
        (
            "preprocess.blur_sigma_mm=1e308",
            ["preprocess.blur_sigma_mm = 1e308", "[0.01, 500] mm"],
        ),
        (
            "preprocess.blur_sigma_mm=1e9",
            ["preprocess.blur_sigma_mm = 1e9", "[0.01, 500] mm"],
        ),
        (
            "detect.sigma_k=nan",
            ["detect.sigma_k = NaN", "finite, in [-10, 10]"],
        ),
        (
            "signal.lowpass_hz=5e-324",
            ["signal.lowpass_hz = 5e-324", "[0.01, 500] Hz"],
        ),
        (
            "signal.lowpass_hz=1e-300",
            ["signal.lowpass_hz = 1e-300", "[0.01, 500] Hz"],
        ),
        (
            "signal.lowpass_hz=10",
            [
                "signal.lowpass_hz = 10",
                "below the Nyquist frequency, 10 Hz",
            ],
        ),
        (
            "signal.lowpass_hz=400",
            [
                "signal.lowpass_hz = 400",
                "below the Nyquist frequency, 10 Hz",
            ],
        ),
    ] {
        let (out, err, written, report) = compile(&rec, &["--set", set]);
        assert_eq!(out.status.code(), Some(2), "{set}: {err}");
        for w in want {
            assert!(err.contains(w), "{set}: want {w:?} in {err}");
        }
        assert!(!written && report.is_none(), "{set}: output written");
        assert!(err.len() < 600, "{set}: {err}");
    }
    // Above the Nyquist frequency of the rate given on the command line, too.
    let (out, err, written, _) = compile(&rec, &["--rate", "6", "--set", "signal.lowpass_hz=4"]);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("below the Nyquist frequency, 3 Hz") && !written,
        "{err}"
    );
}

/// 8 s of one touch sampled at `rate`: a press held from 2 s to 4 s, then a stroke
/// from 4.5 s to 6.5 s at 0.25 m/s.
fn touch_at(rate: f64) -> Array3<f64> {
    let frames = (8.0 * rate) as usize;
    let mut a = quiet(frames, 0.0, 7);
    for t in 0..frames {
        let s = t as f64 / rate;
        if (2.0..4.0).contains(&s) {
            press(&mut a, t, 3.5, 15.0, 2.0);
        }
        if (4.5..6.5).contains(&s) {
            press(&mut a, t, 3.5, 14.0 - (s - 4.5) * 250.0 / 25.4, 1.5);
        }
    }
    a
}

#[test]
fn one_touch_at_20_and_54_hz_lasts_as_long() {
    let dir = tempfile::tempdir().unwrap();
    let slow = write(dir.path(), "at20.npy", &touch_at(20.0));
    let fast = write(dir.path(), "at54.npy", &touch_at(54.0));
    let (o20, e20, _, r20) = compile(&slow, &[]);
    let (o54, e54, _, r54) = compile(&fast, &["--rate", "54"]);
    assert!(
        o20.status.success() && o54.status.success(),
        "{}: {e20}\n{}: {e54}",
        o20.status,
        o54.status
    );
    assert!(
        !e20.contains("warning") && !e54.contains("warning"),
        "{e20}\n{e54}"
    );
    let (r20, r54) = (r20.unwrap(), r54.unwrap());
    assert_eq!(r54["metadata"]["rate_hz"]["value"], 54.0);
    assert_eq!(r54["metadata"]["rate_hz"]["source"], "cli");
    let d = |r: &serde_json::Value| r["duration_s"].as_f64().unwrap();
    let period = |r: &serde_json::Value| r["keyframe_period_ms"].as_f64().unwrap() / 1000.0;
    let tolerance = period(&r20).max(period(&r54));
    // The stimulus is the recording's 8 s (the default preset trims nothing; `paper`'s
    // trim is in seconds too), plus what conditioning adds around them: the
    // ramps, and the silence the low-pass rings out in (under the default preset a
    // time, the same at every rate). `conditioning(rate)` is that addition, measured on
    // one silent frame under the default preset's signal config.
    let conditioning = |rate: f64| {
        let psi: [Vec<f64>; 8] = std::array::from_fn(|_| vec![0.0; 1]);
        let signal = touchc_model::config::Config::default().signal;
        let c = touchc_rendering::condition::condition(&psi, &signal, rate).unwrap();
        (c.output.len() - 1) as f64 / 1000.0 - 1.0 / rate
    };
    let kept = |r: &serde_json::Value, rate: f64| d(r) - conditioning(rate);
    for (r, rate) in [(&r20, 20.0), (&r54, 54.0)] {
        assert!(
            (kept(r, rate) - 8.0).abs() <= tolerance,
            "{rate} Hz: {} s in total, {} s of recording, keyframes every {tolerance} s",
            d(r),
            kept(r, rate)
        );
    }
    // And both render the touch: some trajectory in each.
    assert!(r20["trajectories"].as_u64().unwrap() >= 1);
    assert!(r54["trajectories"].as_u64().unwrap() >= 1);
}
