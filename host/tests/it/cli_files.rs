//! Drives the real `touchc` binary on stimulus and bank files built here.

use crate::bin;

use bin::{ok, refused, touchc};
use std::path::Path;

use touch_protocol::Bank;

use crate::stimuli;

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
    ok(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["name"], "love");
    assert_eq!(v["duration_s"], 1.0);
    assert_eq!(v["keyframes"], 26);
    let bytes = std::fs::metadata(&file).unwrap().len();
    assert_eq!(v["bytes"], bytes);
    assert_eq!(v["bytes_per_second"], bytes as f64);
    assert!(v["crc"].as_str().unwrap().starts_with("ok"));

    let text = touchc(&["inspect", file.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("love (stimulus v3): 1.000 s"));
}

#[test]
fn inspect_refuses_a_corrupted_file_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = stimulus_file(dir.path(), "calming");
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[20] ^= 0x40;
    std::fs::write(&file, bytes).unwrap();
    let out = touchc(&["inspect", file.to_str().unwrap()]);
    let err = refused(&out);
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
    ok(&out);
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
    ok(&out);
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
    assert!(refused(&out).contains("junk.touch"));
    assert!(!out_path.exists());
}

#[test]
fn bank_refuses_a_stimulus_for_another_layout_or_channel_count() {
    let dir = tempfile::tempdir().unwrap();
    let a = stimulus_file(dir.path(), "love");
    let other = dir.path().join("other.touch");
    let bytes = std::fs::read(&a).unwrap();
    std::fs::write(
        &other,
        stimuli::reencoded(&bytes, |b| b.layout("elsewhere", 0x4242)),
    )
    .unwrap();
    let out_path = dir.path().join("sleeve.bank");
    let out = touchc(&[
        "bank",
        a.to_str().unwrap(),
        other.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    let err = refused(&out);
    let target = touch_protocol::layout::SLEEVE_HASH;
    assert!(
        err.contains("other.touch")
            && err.contains("layout \"elsewhere\" (geometry 0x00004242)")
            && err.contains(&format!("layout \"paper-2x4\" (geometry {target:#010x})")),
        "{err}"
    );
    assert!(!out_path.exists());

    // Four channels instead of eight: the header's first byte, re-sealed.
    let mut four = bytes.clone();
    four[10] = 4;
    let n = four.len();
    let crc = touch_protocol::container::crc32(&four[..n - 4]);
    four[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let narrow = dir.path().join("narrow.touch");
    std::fs::write(&narrow, four).unwrap();
    let out = touchc(&[
        "bank",
        narrow.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    let err = refused(&out);
    assert!(
        err.contains("narrow.touch: has 4 channels, but the bank's sleeve has 8"),
        "{err}"
    );
    assert!(!out_path.exists());
}

#[test]
fn bank_refuses_too_many_slots_and_too_many_bytes_with_the_limits() {
    let dir = tempfile::tempdir().unwrap();
    let a = stimulus_file(dir.path(), "love");
    let out_path = dir.path().join("sleeve.bank");
    let a = a.to_str().unwrap();
    let mut args = vec!["bank"];
    args.extend(std::iter::repeat_n(a, 33));
    args.extend(["-o", out_path.to_str().unwrap()]);
    let out = touchc(&args);
    let err = refused(&out);
    assert!(
        err.contains("33 stimuli, but a bank holds at most 32 slots"),
        "{err}"
    );
    assert!(!out_path.exists());

    // 12 s of keyframes that jump every 1 ms on every channel: 17 bytes each, about
    // 200 KB a stimulus, so two do not fit the 256 KB region.
    let frames: Vec<[i16; 8]> = (0..12_000i64)
        .map(|k| [((k * 7919) % 40_001 - 20_000) as i16; 8])
        .collect();
    let love = std::fs::read(a).unwrap();
    let big = touch_protocol::stimulus::Builder::like(
        touch_protocol::Stimulus::decode(&love).unwrap().header(),
    )
    .keyframe_period_ms(1)
    .quant_shift(5)
    .encode(&frames)
    .unwrap();
    let big_path = dir.path().join("big.touch");
    std::fs::write(&big_path, &big).unwrap();
    let big_path = big_path.to_str().unwrap();
    let out = touchc(&["bank", big_path, big_path, "-o", out_path.to_str().unwrap()]);
    let err = refused(&out);
    let total = 10 + 2 + 4 + 16 + 2 * big.len() + 4;
    assert!(
        err.contains(&format!(
            "bank image of {total} bytes does not fit the sleeve's 262144-byte bank flash region"
        )),
        "{} bytes each: {err}",
        big.len()
    );
    assert!(!out_path.exists());
}

/// The paper's layout with its rows swapped, still called `paper-2x4`: a name proves
/// nothing about geometry, so the bank must refuse what this compiles.
#[test]
fn bank_refuses_a_mirrored_layout_that_kept_the_sleeves_name() {
    let dir = tempfile::tempdir().unwrap();
    let paper = touchc_model::layout::Layout::paper();
    let mut toml = String::from("id = \"paper-2x4\"\n");
    for w in paper.workspaces() {
        toml += &format!(
            "[[workspace]]\nchannel = {}\nrow = {}\ncolumn = {}\nx_mm = {}\ny_mm = {}\nradius_mm = {}\nweight = {}\n",
            w.channel,
            w.row,
            w.column,
            w.x_mm,
            50.0 - w.y_mm,
            w.radius_mm,
            w.weight
        );
    }
    let mirrored = dir.path().join("mirrored.toml");
    std::fs::write(&mirrored, toml).unwrap();
    let recording = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/tap_pat.npy");
    let touch = dir.path().join("tap.touch");
    ok(&touchc(&[
        "compile",
        bin::s(&recording),
        "--layout",
        bin::s(&mirrored),
        "-o",
        bin::s(&touch),
    ]));
    let out_path = dir.path().join("sleeve.bank");
    let err = refused(&touchc(&["bank", bin::s(&touch), "-o", bin::s(&out_path)]));
    let ours = touch_protocol::layout::SLEEVE_HASH;
    assert!(
        err.contains("tap.touch") && err.contains(&format!("(geometry {ours:#010x})")),
        "{err}"
    );
    assert!(!out_path.exists());
    // The same file banked for the layout it was compiled for is accepted.
    ok(&touchc(&[
        "bank",
        bin::s(&touch),
        "--layout",
        bin::s(&mirrored),
        "-o",
        bin::s(&out_path),
    ]));
}
