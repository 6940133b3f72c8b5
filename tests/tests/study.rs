//! `touchc study run` end to end: the real binary against the in-memory sleeve (the
//! firmware's engine and link server, `sleeve_firmware::link::sim`) behind a
//! pseudo-terminal, a scripted participant answering over the page's HTTP interface,
//! the run killed mid-round and resumed, then `touchc study report` on the log.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[path = "common/pty_sleeve.rs"]
mod pty_sleeve;

/// Device milliseconds per host millisecond: the sleeve runs faster than life, so a
/// session of 3-second stimuli takes seconds.
const SPEED: usize = 10;

fn sleeve(stop: Arc<AtomicBool>) -> String {
    pty_sleeve::serve(SPEED, stop)
}

/// The `touchc` binary, built first: it is another package's, so Cargo does not
/// build it for this crate's tests.
fn touchc() -> std::path::PathBuf {
    static BUILT: std::sync::Once = std::sync::Once::new();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    BUILT.call_once(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let ok = Command::new(cargo)
            .args(["build", "-q", "-p", "touchc", "--bin", "touchc"])
            .current_dir(&root)
            .status()
            .unwrap();
        assert!(ok.success(), "touchc builds");
    });
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or(root.join("target"), Into::into);
    target.join("debug").join("touchc")
}

fn http(addr: &str, method: &str, path: &str, body: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).expect("the page's server answers");
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let status = text[9..12].parse().unwrap();
    let body = text
        .split_once("\r\n\r\n")
        .map(|x| x.1)
        .unwrap_or("")
        .to_string();
    (status, body)
}

fn start(plan: &Path, port: &str, log: &Path, resume: bool) -> (Child, String) {
    let mut cmd = Command::new(touchc());
    cmd.args(["study", "run"])
        .arg(plan)
        .args([
            "--participant",
            "t1",
            "--port",
            port,
            "--http-port",
            "0",
            "--log",
        ])
        .arg(log);
    if resume {
        cmd.arg("--resume");
    }
    let mut child = cmd.stderr(Stdio::piped()).spawn().expect("touchc runs");
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let first = lines.next().expect("a first line").unwrap();
    let url = first
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap_or_else(|| panic!("{first}"));
    let addr = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    // Keep draining the progress lines so that touchc never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    (child, addr)
}

/// Answers until `answers` trials were answered (then returns at once) or the
/// session is done. Returns the number answered.
fn participant(addr: &str, n: usize, answers: Option<usize>) -> usize {
    let mut last = 0u64;
    let mut given = 0;
    let until = Instant::now() + Duration::from_secs(240);
    while Instant::now() < until {
        let (_, body) = http(addr, "GET", "/state", "");
        let s: serde_json::Value = serde_json::from_str(&body).unwrap();
        let id = s["id"].as_u64().unwrap();
        match s["phase"].as_str().unwrap() {
            "intro" => assert_eq!(http(addr, "POST", "/start", "").0, 200),
            "classify" if id != last => {
                // A tie for the largest is refused.
                let tie = serde_json::json!({"id": id, "p": vec![1.0; n]}).to_string();
                assert_eq!(http(addr, "POST", "/answer", &tie).0, 409);
                let p: Vec<f64> = (0..n)
                    .map(|i| {
                        if i as u64 == id % n as u64 {
                            5.0
                        } else {
                            1.0 + i as f64 / 10.0
                        }
                    })
                    .collect();
                let a = serde_json::json!({"id": id, "p": p}).to_string();
                assert_eq!(http(addr, "POST", "/answer", &a).0, 200);
                (last, given) = (id, given + 1);
            }
            "sam" if id != last => {
                let a = serde_json::json!({"id": id, "valence": 1 + id % 9, "arousal": 9 - id % 9})
                    .to_string();
                assert_eq!(http(addr, "POST", "/answer", &a).0, 200);
                (last, given) = (id, given + 1);
            }
            "done" => return given,
            _ => {}
        }
        if answers == Some(given) {
            return given;
        }
        std::thread::sleep(Duration::from_millis(30));
    }
    panic!("the session did not finish in time ({given} answers)");
}

#[test]
fn a_scripted_participant_completes_a_session_that_is_killed_and_resumed() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plan.toml");
    let example = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/study/emoji.toml"),
    )
    .unwrap();
    // The example plan, shorter: two rounds, a short pause after a refusal.
    let text = example
        .replace("rounds = 3", "rounds = 2")
        .replace("retry_pause_s = 5.0", "retry_pause_s = 0.2");
    std::fs::write(&plan, text).unwrap();
    let log = dir.path().join("t1.jsonl");
    let stop = Arc::new(AtomicBool::new(false));
    let port = sleeve(stop.clone());

    let (mut first, addr) = start(&plan, &port, &log, false);
    assert_eq!(participant(&addr, 6, Some(7)), 7);
    // Mid-trial: the eighth stimulus plays or waits for its answer.
    std::thread::sleep(Duration::from_millis(300));
    first.kill().unwrap();
    first.wait().unwrap();
    let kept = touchc_study_trials(&log);
    assert_eq!(kept.len(), 7, "every answered trial is in the log");

    let (mut second, addr) = start(&plan, &port, &log, true);
    participant(&addr, 6, None);
    assert!(second.wait().unwrap().success());
    stop.store(true, Ordering::Relaxed);

    let trials = touchc_study_trials(&log);
    assert_eq!(trials.len(), 2 * 6 + 6, "two rounds and the manikin round");
    let mut seen: Vec<(u64, u64)> = trials
        .iter()
        .map(|t| {
            (
                t["round"].as_u64().unwrap(),
                t["position"].as_u64().unwrap(),
            )
        })
        .collect();
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), trials.len(), "no trial repeated");
    for t in &trials {
        let (a, b) = (
            t["start_tick"].as_u64().unwrap(),
            t["end_tick"].as_u64().expect("the end was heard"),
        );
        assert!(b > a + 100, "{t}");
    }
    let out = dir.path().join("report");
    let status = Command::new(touchc())
        .args(["study", "report"])
        .arg(&log)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["trials"], 12);
    assert_eq!(
        report["valence"]["count"],
        serde_json::json!([1, 1, 1, 1, 1, 1])
    );
}

fn touchc_study_trials(log: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["kind"] == "trial")
        .collect()
}
