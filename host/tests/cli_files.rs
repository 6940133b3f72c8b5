//! Drives the real `touchc` binary on stimulus and bank files built here.

#[path = "common/bin.rs"]
mod bin;

use bin::touchc;
use std::path::Path;

use touch_protocol::Bank;

#[path = "common/stimuli.rs"]
mod stimuli;

fn stimulus_file(dir: &Path, name: &str) -> std::path::PathBuf {
    // A 4 Hz-ish swell on channel 2 over a -0.9 A pre-dent elsewhere, 1 s long.
    let swell: stimuli::Shape = |x| -0.9 + 1.9 * (std::f64::consts::PI * x).sin().powi(2);
    let bytes = stimuli::stimulus(name, &stimuli::one_second(-0.9, &[(2, swell)]));
    let path = dir.join(format!("{name}.touch"));
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn inspect_reports_header_size_and_crc() {
    let dir = tempfile::tempdir().unwrap();
    let file = stimulus_file(dir.path(), "love");
    let out = touchc(&["inspect", file.to_str().unwrap(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["name"], "love");
    assert_eq!(v["duration_s"], 1.0);
    assert_eq!(v["keyframes"], 26);
    let bytes = std::fs::metadata(&file).unwrap().len();
    assert_eq!(v["bytes"], bytes);
    assert_eq!(v["bytes_per_second"], bytes as f64);
    assert!(v["crc"].as_str().unwrap().starts_with("ok"));

    let text = touchc(&["inspect", file.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("love (stimulus v1): 1.000 s"));
}

#[test]
fn inspect_refuses_a_corrupted_file_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = stimulus_file(dir.path(), "calming");
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[20] ^= 0x40;
    std::fs::write(&file, bytes).unwrap();
    let out = touchc(&["inspect", file.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("calming.touch") && err.contains("CRC"),
        "{err}"
    );
}

#[test]
fn render_csv_is_the_players_output_in_amperes() {
    let dir = tempfile::tempdir().unwrap();
    let file = stimulus_file(dir.path(), "love");
    let csv_path = dir.path().join("love.csv");
    let out = touchc(&[
        "render",
        file.to_str().unwrap(),
        "--csv",
        "-o",
        csv_path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(
        csv.lines().next().unwrap(),
        "t_s,ch0,ch1,ch2,ch3,ch4,ch5,ch6,ch7"
    );
    // 1001 signal ticks, 10 ramp ticks, and the final idle tick.
    assert_eq!(rows.len(), 1001 + 10);
    assert_eq!(rows[500][0], 0.5);
    // Mid-signal: channel 2 swells to +1 A, the others hold the -0.9 A pre-dent.
    // (keyframes at 0.48 s and 0.52 s: sin^2 = 0.996 there)
    assert!((rows[500][3] - 0.9925).abs() < 0.002, "{}", rows[500][3]);
    assert!((rows[500][1] + 0.9).abs() < 0.002, "{}", rows[500][1]);
    // Starts and ends at 0 A.
    assert!(rows[0][1..].iter().all(|a| a.abs() < 0.01));
    assert!(rows.last().unwrap()[1..].iter().all(|&a| a == 0.0));
}

#[test]
fn bank_packs_slots_in_order_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let a = stimulus_file(dir.path(), "love");
    let b = stimulus_file(dir.path(), "calming");
    let bank_path = dir.path().join("sleeve.bank");
    let out = touchc(&[
        "bank",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "-o",
        bank_path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let image = std::fs::read(&bank_path).unwrap();
    let bank = Bank::decode(&image).unwrap();
    let names: Vec<_> = bank.stimuli().map(|s| s.name()).collect();
    assert_eq!(names, ["love", "calming"]);

    let v: serde_json::Value =
        serde_json::from_slice(&touchc(&["inspect", bank_path.to_str().unwrap(), "--json"]).stdout)
            .unwrap();
    assert_eq!(v["kind"], "bank");
    assert_eq!(v["slots"][1]["name"], "calming");

    // A non-stimulus input: clear error naming it, and no bank written.
    let junk = dir.path().join("junk.touch");
    std::fs::write(&junk, b"not a stimulus").unwrap();
    let out_path = dir.path().join("bad.bank");
    let out = touchc(&[
        "bank",
        a.to_str().unwrap(),
        junk.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("junk.touch"));
    assert!(!out_path.exists());
}
