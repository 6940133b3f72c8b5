//! `touchc study` as a user meets its refusals: no sleeve, a bad plan, a log that
//! exists, bad report inputs; and a report's files from a tidy CSV. (A whole session
//! runs against the in-memory sleeve in the end-to-end crate, tests/study.rs, and in
//! headless Chromium, scripts/study-browser.sh.)

use crate::bin::{stderr, touchc};

const PLAN: &str = "../examples/study/emoji.toml";

fn serial_ports_attached() -> bool {
    std::fs::read_dir("/dev").is_ok_and(|d| {
        d.flatten().any(|e| {
            let n = e.file_name();
            let n = n.to_string_lossy();
            n.starts_with("ttyACM") || n.starts_with("ttyUSB")
        })
    })
}

#[test]
fn with_no_sleeve_attached_run_says_so_in_one_line_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("p.jsonl");
    let mut args = vec![
        "study",
        "run",
        PLAN,
        "--participant",
        "p01",
        "--log",
        log.to_str().unwrap(),
    ];
    if serial_ports_attached() {
        args.extend(["--port", "/dev/no-such-sleeve"]);
    }
    let out = touchc(&args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no sleeve attached"), "{err}");
    assert!(!log.exists(), "no log without a sleeve");
}

#[test]
fn a_bad_plan_names_the_file_the_key_and_the_problem_and_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string(PLAN).unwrap();
    for (from, to, key, problem) in [
        ("slot = 3", "slot = \"x\"", "`slot`", "invalid type"),
        (
            "slot = 3",
            "slot = 0",
            "`scenario[1].slot`",
            "slot 0 is \"attention\"'s too",
        ),
        (
            "rounds = 3",
            "rounds = 99",
            "`rounds`",
            "99 is not in 0..=20",
        ),
        (
            "name = \"love\"",
            "name = \"calming\"",
            "`scenario[4].name`",
            "named twice",
        ),
        (
            "replay = false",
            "replay = false\nfrobnicate = 1",
            "`frobnicate`",
            "unknown field",
        ),
        ("seed = 37", "", "`seed`", "missing field `seed`"),
        (
            "prompt = \"Imagine this: You're at",
            "# prompt = \"",
            "`scenario.prompt`",
            "missing field `prompt`",
        ),
    ] {
        let plan = dir.path().join("plan.toml");
        std::fs::write(&plan, example.replacen(from, to, 1)).unwrap();
        let p = plan.to_str().unwrap();
        let out = touchc(&[
            "study",
            "run",
            p,
            "--participant",
            "p01",
            "--port",
            "/dev/no-such-sleeve",
        ]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{to}: {err}");
        assert!(
            err.contains(p) && err.contains(key) && err.contains(problem),
            "{to}: {err}"
        );
    }
}

#[test]
fn an_existing_log_is_continued_only_with_resume() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("p.jsonl");
    std::fs::write(&log, "").unwrap();
    let l = log.to_str().unwrap();
    let out = touchc(&[
        "study",
        "run",
        PLAN,
        "--participant",
        "p01",
        "--log",
        l,
        "--port",
        "/dev/no-such-sleeve",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--resume"), "{}", stderr(&out));
    let out = touchc(&[
        "study",
        "run",
        PLAN,
        "--participant",
        "p 1",
        "--port",
        "/dev/no-such-sleeve",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

const CSV: &str = "participant,round,position,stimulus,p_a,p_b,p_c,valence,arousal\n\
    p1,1,1,a,0.7,0.2,0.1,,\n\
    p1,1,2,b,0.1,0.6,0.3,,\n\
    p1,1,3,c,0.5,0.3,0.2,,\n\
    p1,2,1,a,,,,7,3\n\
    p1,2,2,b,,,,2,8\n\
    p1,2,3,c,,,,5,5\n";

#[test]
fn report_writes_its_files_and_reads_its_own_csv_back() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("in.csv");
    std::fs::write(&csv, CSV).unwrap();
    let out_dir = dir.path().join("r");
    let out = touchc(&[
        "study",
        "report",
        csv.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    for f in [
        "report.json",
        "report.md",
        "trials.csv",
        "confusion.csv",
        "confusion.svg",
        "cutoff.svg",
        "sam.svg",
    ] {
        assert!(out_dir.join(f).is_file(), "{f}");
    }
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(
        r["confusion"],
        serde_json::json!([[1, 0, 0], [0, 1, 0], [1, 0, 0]])
    );
    assert_eq!(r["accuracy"]["correct"], 2);
    // The tidy CSV it wrote reads back to the same analysis.
    let again = dir.path().join("again");
    let t = out_dir.join("trials.csv");
    let out = touchc(&[
        "study",
        "report",
        t.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r2: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(again.join("report.json")).unwrap()).unwrap();
    assert_eq!(r2["confusion"], r["confusion"]);
    assert_eq!(r2["valence"], r["valence"]);
    // Markdown on stdout without -o.
    let out = touchc(&["study", "report", csv.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("Top-choice accuracy: **66.7 %**"));
}

#[test]
fn bad_report_inputs_name_the_file_and_line_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("bad.csv");
    std::fs::write(&csv, CSV.replace("0.6", "lots")).unwrap();
    let out_dir = dir.path().join("r");
    let c = csv.to_str().unwrap();
    let out = touchc(&["study", "report", c, "-o", out_dir.to_str().unwrap()]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(c) && err.contains("line 3") && err.contains("p_b"),
        "{err}"
    );
    assert!(!out_dir.exists(), "no partial output");
}
