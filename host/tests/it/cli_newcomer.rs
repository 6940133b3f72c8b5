//! What a newcomer and an adversary found (issue 34): a closed standard output is an
//! error, endless inputs end, messages keep their advice.

use crate::bin;
use crate::stimuli;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use bin::{command, s, stderr};

/// A 1 s stimulus in `dir`.
fn stimulus(dir: &Path) -> PathBuf {
    let path = dir.join("one.touch");
    let swell: stimuli::Shape = |x| 0.5 * (std::f64::consts::PI * x).sin();
    let bytes = stimuli::stimulus("one", &stimuli::one_second(0.0, &[(2, swell)]));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Runs `touchc args` through `bash` with `redirect` (`>&-`, `</dev/zero`), under a
/// 2 GB address-space limit, and kills it after `limit`: returns its output, or `None`
/// when it had to be killed.
fn shell(redirect: &str, args: &[&str], limit: Duration) -> Option<Output> {
    let script = format!("ulimit -v 2000000; exec \"$0\" \"$@\" {redirect}");
    let mut child = Command::new("bash")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_touchc"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Some(child.wait_with_output().unwrap())
}

#[test]
fn a_closed_standard_output_is_an_error_not_a_success() {
    let dir = tempfile::tempdir().unwrap();
    let touch = stimulus(dir.path());
    let t = s(&touch);
    let runs: [&[&str]; 7] = [
        &["compile", "../examples/tap_pat.npy", "-o", "-"],
        &["render", t, "--csv"],
        &["render", t, "--wav", "-"],
        &["inspect", t],
        &["export", t, "--to", "hjif", "-o", "-"],
        &["track", "../examples/stroke.npy", "--json"],
        &["completions", "bash"],
    ];
    for args in runs {
        let out = shell(">&-", args, Duration::from_secs(120)).expect("finishes");
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("cannot write standard output: it is closed"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("->"), "{args:?} claims an output: {err}");
    }
}

/// `-o /dev/stdout` and its other names reach descriptor 1, which the runtime reopened
/// on `/dev/null` when it was closed: they must fail as `-o -` does, while an explicit
/// `-o /dev/null` still succeeds.
#[test]
fn a_closed_standard_output_named_by_a_path_is_an_error_too() {
    let dir = tempfile::tempdir().unwrap();
    let touch = stimulus(dir.path());
    let t = s(&touch);
    let rec = "../examples/tap_pat.npy";
    let runs: [&[&str]; 6] = [
        &["compile", rec, "-o", "/dev/stdout"],
        &["compile", rec, "-o", "/proc/self/fd/1"],
        &["compile", rec, "-o", "/dev/fd/1"],
        &["render", t, "--csv", "-o", "/dev/stdout"],
        &["render", t, "--wav", "/proc/self/fd/1"],
        &["export", t, "--to", "hjif", "-o", "/dev/stdout"],
    ];
    for args in runs {
        let out = shell(">&-", args, Duration::from_secs(120)).expect("finishes");
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("it is closed"), "{args:?}: {err}");
        assert!(!err.contains("->"), "{args:?} claims an output: {err}");
    }
    let out = shell(
        ">&-",
        &["compile", rec, "-o", "/dev/null"],
        Duration::from_secs(120),
    )
    .expect("finishes");
    assert_eq!(out.status.code(), Some(0), "-o /dev/null: {}", stderr(&out));
}

#[test]
fn endless_inputs_end_in_an_error_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let bank = dir.path().join("b.bank");
    let runs: [(&str, Vec<&str>); 9] = [
        ("", vec!["inspect", "/dev/zero"]),
        ("", vec!["compile", "/dev/zero", "-o", "/dev/null"]),
        ("", vec!["render", "/dev/urandom", "--csv"]),
        ("", vec!["track", "/dev/zero"]),
        ("", vec!["bank", "/dev/zero", "-o", s(&bank)]),
        ("</dev/zero", vec!["import", "-", "-o", "/dev/null"]),
        (
            "</dev/zero",
            vec!["export", "-", "--to", "hjif", "-o", "/dev/null"],
        ),
        ("</dev/zero", vec!["compile", "-", "-o", "/dev/null"]),
        ("</dev/urandom", vec!["inspect", "-"]),
    ];
    for (redirect, args) in runs {
        let out = shell(redirect, &args, Duration::from_secs(30))
            .unwrap_or_else(|| panic!("{args:?} {redirect}: still reading after 30 s"));
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?} {redirect}: {err}");
        assert!(!err.contains("memory"), "{args:?} {redirect}: {err}");
        assert!(!bank.exists());
    }
}

#[test]
fn an_endless_stream_after_a_valid_header_reads_only_what_the_header_claims() {
    let dir = tempfile::tempdir().unwrap();
    let head = dir.path().join("head.npy");
    let redirect = format!("< <(cat {} /dev/zero)", s(&head));
    let args = ["compile", "-", "-o", "/dev/null"];
    // A .npy header for 100 frames of the paper's sleeve, then zeros without end.
    std::fs::write(&head, crate::poison::npy("<f8", false, "(100, 8, 21)", &[])).unwrap();
    let out = shell(&redirect, &args, Duration::from_secs(30)).expect("finishes");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("unexpected bytes after the data"), "{err}");

    // A header claiming more than a stream may bring is refused before its data.
    let big = crate::poison::npy("<f8", false, "(100000000, 8, 21)", &[]);
    std::fs::write(&head, big).unwrap();
    let out = shell(&redirect, &args, Duration::from_secs(30)).expect("finishes");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("read from a stream"), "{err}");
}

#[test]
fn warnings_keep_their_advice_whatever_the_file_is_called() {
    let dir = tempfile::tempdir().unwrap();
    let deep = dir.path().join("d".repeat(200)).join("e".repeat(200));
    std::fs::create_dir_all(&deep).unwrap();
    let input = deep.join("tap_pat.npy");
    std::fs::copy("../examples/tap_pat.npy", &input).unwrap();
    let out = command()
        .args(["compile", s(&input), "-o", s(&deep.join("t.touch"))])
        .args(["--max-trajectories", "2"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert!(warnings.len() >= 2, "{err}");
    for line in &warnings {
        assert!(!line.contains("more characters"), "cut: {line}");
        assert!(
            !line.contains(&"d".repeat(81)),
            "the name is not clipped: {line}"
        );
    }
    assert!(
        err.contains("raise it with --max-trajectories (coverage"),
        "{err}"
    );

    // A batch prints each recording's warnings whole too.
    let second = deep.join("again.npy");
    std::fs::copy(&input, &second).unwrap();
    let out = command()
        .args(["compile", s(&input), s(&second), "--out-dir", s(&deep)])
        .args(["--max-trajectories", "2"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert!(warnings.len() >= 4, "{err}");
    for line in &warnings {
        assert!(!line.contains("more characters"), "cut: {line}");
    }
}

/// `tap_pat.npy` as the `pressure` of an archive that declares `rate_hz`.
fn tap_pat_at(dir: &Path, rate_hz: f64) -> PathBuf {
    use crate::poison::{scalar_npy, zip, Entry};
    let pressure = std::fs::read("../examples/tap_pat.npy").unwrap();
    let rate = scalar_npy("<f8", &rate_hz.to_le_bytes());
    let path = dir.join(format!("at{rate_hz}.npz"));
    let entries = [
        Entry::stored("pressure.npy", pressure),
        Entry::stored("rate_hz.npy", rate),
    ];
    std::fs::write(&path, zip(&entries)).unwrap();
    path
}

#[test]
fn a_files_impossible_rate_is_bad_input_that_names_the_rate() {
    let dir = tempfile::tempdir().unwrap();
    for rate in [1.0, 3.0] {
        let npz = tap_pat_at(dir.path(), rate);
        let out_touch = dir.path().join("x.touch");
        let runs: [&[&str]; 2] = [
            &["compile", s(&npz), "-o", s(&out_touch)],
            &["track", s(&npz)],
        ];
        for args in runs {
            let out = command().args(args).output().unwrap();
            let err = stderr(&out);
            assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
            assert!(err.contains(&format!("rate_hz = {rate} Hz")), "{err}");
            assert!(err.contains(s(&npz)), "{err}");
        }
        assert!(!out_touch.exists());
    }
    // The same rate given on the command line is the command line's mistake.
    let npz = tap_pat_at(dir.path(), 20.0);
    let out = command()
        .args(["track", s(&npz), "--rate", "1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[test]
fn a_stimulus_whose_limits_let_nothing_move_says_so() {
    use touch_protocol::Limits;
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read(stimulus(dir.path())).unwrap();
    let zero_peak = Limits {
        peak_ma: 0,
        ..Limits::SLEEVE
    };
    let zero_slew = Limits {
        slew_ma_per_ms: 0,
        ..Limits::SLEEVE
    };
    for (what, limits) in [("peak", zero_peak), ("slew", zero_slew)] {
        let path = dir.path().join(format!("{what}.touch"));
        std::fs::write(&path, stimuli::reencoded(&good, |b| b.limits(limits))).unwrap();
        let plot = dir.path().join("p.svg");
        let runs: [&[&str]; 3] = [
            &["render", s(&path), "--csv"],
            &["plot", s(&path), "-o", s(&plot)],
            &["export", s(&path), "--to", "hjif", "-o", "/dev/null"],
        ];
        for args in runs {
            let out = command().args(args).output().unwrap();
            let err = stderr(&out);
            assert!(out.status.success(), "{args:?}: {err}");
            assert!(err.contains("warning"), "{what} {args:?}: {err}");
            assert!(err.contains("can never play"), "{what} {args:?}: {err}");
        }
    }
}

#[test]
fn export_names_and_slots_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let touch = stimulus(dir.path());
    let t = s(&touch);
    let y = dir.path().join("y.touch");
    let refused: [&[&str]; 4] = [
        &["export", t, "--to", "haptic", "-o", "/dev/full"],
        &["export", t, "--to", "ahap", "-o", s(&y)],
        &[
            "export",
            t,
            "--to",
            "hjif",
            "--slot",
            "3",
            "-o",
            "/dev/null",
        ],
        &["render", t, "--csv", "--slot", "1"],
    ];
    for args in refused {
        let out = command().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    }
    let mut names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names, ["one.touch"]);
    // A slot beyond the bank says how many it has, whatever number was typed.
    let bank = dir.path().join("b.bank");
    let out = command()
        .args(["bank", t, t, "-o", s(&bank)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let args = ["export", s(&bank), "--to", "hjif"];
    let out = command()
        .args(args)
        .args(["--slot", "99999999999", "-o", "/dev/null"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no slot 99999999999: the bank has 2 slot(s), 0 to 1"),
        "{err}"
    );
}

#[test]
fn a_placement_grid_no_sensor_can_use_is_refused_before_any_work() {
    let out = command()
        .args(["compile", "../examples/tap_pat.npy", "-o", "/dev/null"])
        .args([
            "--set",
            "placement.grid_x=20000000",
            "--set",
            "placement.grid_y=1",
        ])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("placement.grid_x = 20000000 is out of range"),
        "{err}"
    );
}

#[test]
fn an_absurd_hjif_amplitude_is_named_in_a_few_characters() {
    let dir = tempfile::tempdir().unwrap();
    let touch = stimulus(dir.path());
    let hjif = dir.path().join("x.hjif");
    let out = command()
        .args(["export", s(&touch), "--to", "hjif", "-o", s(&hjif)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&hjif).unwrap();
    let key = "\"amplitude_modulation\":";
    let at = text.find(key).expect("an amplitude") + key.len();
    let end = at + text[at..].find([',', '}']).unwrap();
    let absurd = format!("{}1e308{}", &text[..at], &text[end..]);
    std::fs::write(&hjif, absurd).unwrap();
    let out = command()
        .args(["import", s(&hjif), "-o", "/dev/null"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("amplitude 1e308 outside"), "{err}");
    assert!(err.len() < 300, "{err}");
}

#[test]
fn raw_adc_counts_compile_with_the_counts_warning_and_a_csv_says_how_to_convert() {
    use ndarray_npy::{ReadNpyExt, WriteNpyExt};
    let dir = tempfile::tempdir().unwrap();
    let file = std::fs::File::open("../examples/tap_pat.npy").unwrap();
    let psi = ndarray::Array3::<f64>::read_npy(file).unwrap();
    // A 10-bit ADC's counts: a baseline of 512, 100 counts a psi, no NaN.
    let counts = psi.mapv(|v| {
        if v.is_nan() {
            512
        } else {
            512 + (100.0 * v).round() as i16
        }
    });
    let path = dir.path().join("counts.npy");
    counts
        .write_npy(std::fs::File::create(&path).unwrap())
        .unwrap();
    let out = command()
        .args(["compile", s(&path), "-o", s(&dir.path().join("c.touch"))])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("the median reading is 512"), "{err}");

    let csv = dir.path().join("rec.csv");
    std::fs::write(&csv, "0.1,0.2,0.0\n0.0,0.3,0.1\n").unwrap();
    let out = command()
        .args(["compile", s(&csv), "-o", s(&dir.path().join("r.touch"))])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("text, not a .npy or .npz file"), "{err}");
    assert!(err.contains("np.loadtxt("), "{err}");
    assert!(err.contains("reshape(-1, ROWS, COLS))'"), "{err}");
}

#[test]
fn a_recording_given_where_a_stimulus_goes_says_to_compile_it_first() {
    let dir = tempfile::tempdir().unwrap();
    let bank = dir.path().join("b.bank");
    let npy = "../examples/stroke.npy";
    let runs: [&[&str]; 3] = [
        &["inspect", npy],
        &["export", npy, "--to", "hjif", "-o", "/dev/null"],
        &["bank", npy, "-o", s(&bank)],
    ];
    for args in runs {
        let out = command().args(args).output().unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("compile it into a stimulus first"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn help_and_tables_give_usable_figures_and_units() {
    let out = command().args(["compile", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("[default: 10.886, rounded]"), "{help}");
    assert!(!help.contains("10.8857142"), "{help}");
    let out = command()
        .args(["track", "../examples/tap_pat.npy"])
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("start r,c px"), "{table}");
}

/// The README's lines that install the completions, run as written by a new account.
#[test]
fn the_readmes_completion_lines_work_on_a_fresh_account() {
    let readme = std::fs::read_to_string("../README.md").unwrap();
    let lines: Vec<&str> = readme
        .lines()
        .filter(|l| l.starts_with("mkdir -p ~") || l.starts_with("touchc completions "))
        .collect();
    assert!(lines.len() >= 6, "{lines:?}");
    let home = tempfile::tempdir().unwrap();
    let bin = std::path::Path::new(env!("CARGO_BIN_EXE_touchc"))
        .parent()
        .unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for line in &lines {
        let out = Command::new("bash")
            .args(["-euc", line])
            .env("HOME", home.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(out.status.success(), "{line}: {}", stderr(&out));
    }
    for f in [
        ".local/share/bash-completion/completions/touchc",
        ".zfunc/_touchc",
        ".config/fish/completions/touchc.fish",
    ] {
        let len = std::fs::metadata(home.path().join(f)).map_or(0, |m| m.len());
        assert!(len > 1000, "{f}: {len} bytes");
    }
}

/// One stimulus, three lengths: each command says which one it gives.
#[test]
fn compile_inspect_and_export_say_which_length_they_give() {
    let dir = tempfile::tempdir().unwrap();
    let touch = dir.path().join("stroke.touch");
    let out = command()
        .args(["compile", "../examples/stroke.npy", "-o", s(&touch)])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(err.contains(", 7.14 s of signal,"), "{err}");
    let out = command().args(["inspect", s(&touch)]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("7.150 s of keyframes (plays 7.160 s with the 10 ms ramp down)"),
        "{text}"
    );
    let out = command()
        .args(["export", s(&touch), "--to", "hjif", "-o", "/dev/null"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(err.contains(": plays 7.16 s,"), "{err}");
}

#[test]
fn trade_says_why_a_preset_is_far_from_exact() {
    let out = command()
        .args(["trade", "../examples/tap_pat.npy", "--preset", "touch"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("note: max vs exact over 100% of full scale"),
        "{err}"
    );
    assert!(err.contains("note: tracks agree 0"), "{err}");
}

#[test]
fn endless_parameter_files_end_in_an_error() {
    let runs: [&[&str]; 3] = [
        &[
            "compile",
            "../examples/tap_pat.npy",
            "-o",
            "/dev/null",
            "--config",
            "/dev/zero",
        ],
        &[
            "compile",
            "../examples/tap_pat.npy",
            "-o",
            "/dev/null",
            "--layout",
            "/dev/zero",
        ],
        &["trade", "../examples/tap_pat.npy", "--truth", "/dev/zero"],
    ];
    for args in runs {
        let out = shell("", args, Duration::from_secs(60))
            .unwrap_or_else(|| panic!("{args:?}: still reading after 60 s"));
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?}: {err}");
        assert!(err.contains("more than"), "{args:?}: {err}");
    }
}
