//! What `touchc synth` writes: a `.npz` numpy can read that carries the sensor's rate
//! and pitch, so the recording compiles at its own rate; a `.npy` of a sensor other
//! than the sleeve comes with the flags its compile needs.

use std::io::Read;

use crate::bin::{ok, s, stderr, touchc};
use ndarray::{Array0, Array3};
use ndarray_npy::ReadNpyExt;

/// The members of a zip archive, by name, read with a zip reader of its own (not
/// touchc's `.npz` reader).
fn members(path: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let file = std::fs::File::open(path).unwrap();
    let mut zip = zip::ZipArchive::new(file).unwrap();
    (0..zip.len())
        .map(|i| {
            let mut m = zip.by_index(i).unwrap();
            let mut bytes = Vec::new();
            m.read_to_end(&mut bytes).unwrap();
            (m.name().to_string(), bytes)
        })
        .collect()
}

fn report(dir: &std::path::Path, rec: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let json = dir.join("report.json");
    let out_path = dir.join("out.touch");
    let mut args = vec!["compile", s(rec), "-o", s(&out_path), "--report", s(&json)];
    args.extend_from_slice(extra);
    ok(&touchc(&args));
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

/// `-o x.npz` writes a real archive (it used to write `.npy` bytes): `np.savez`'s
/// member names, each a `.npy` a numpy reader parses, with the grid sensor's 54 Hz
/// and one-inch pitch; touchc compiles it at 54 Hz with no flag, as long as the same
/// array given as a `.npy` with `--rate 54`.
#[test]
fn a_synthetic_npz_carries_its_rate_and_compiles_at_it() {
    let dir = tempfile::tempdir().unwrap();
    let npz = dir.path().join("c.npz");
    ok(&touchc(&[
        "synth",
        "stroke",
        "--sensor",
        "grid10",
        "-o",
        s(&npz),
    ]));
    let bytes = std::fs::read(&npz).unwrap();
    assert!(bytes.starts_with(b"PK\x03\x04"), "not a zip archive");
    let members = members(&npz);
    let names: Vec<&str> = members.iter().map(|m| m.0.as_str()).collect();
    assert_eq!(names, ["pressure.npy", "rate_hz.npy", "pitch_mm.npy"]);
    let pressure = Array3::<f64>::read_npy(&members[0].1[..]).unwrap();
    assert_eq!((pressure.dim().1, pressure.dim().2), (10, 10));
    let rate = Array0::<f64>::read_npy(&members[1].1[..]).unwrap();
    let pitch = Array0::<f64>::read_npy(&members[2].1[..]).unwrap();
    assert_eq!((rate.into_scalar(), pitch.into_scalar()), (54.0, 25.4));

    let rec = touchc_input::recording::Recording::load(&npz).unwrap();
    assert_eq!(rec.file_rate_hz(), Some(54.0));
    assert_eq!(rec.file_pitch_mm(), Some(25.4));
    let from_npz = report(dir.path(), &npz, &[]);
    assert_eq!(from_npz["metadata"]["rate_hz"]["value"], 54.0);
    assert_eq!(from_npz["metadata"]["rate_hz"]["source"], "file");

    // The same array as a .npy, compiled with the rate given by hand.
    let npy = dir.path().join("c.npy");
    std::fs::write(&npy, touchc_synth::to_npy(&pressure).unwrap()).unwrap();
    let from_npy = report(dir.path(), &npy, &["--rate", "54"]);
    assert_eq!(from_npz["duration_s"], from_npy["duration_s"]);
    let at_default = report(dir.path(), &npy, &[]);
    assert!(
        at_default["duration_s"].as_f64() > from_npz["duration_s"].as_f64(),
        "the file's rate is what makes it shorter"
    );
}

/// A `.npy` holds no rate: for the 54 Hz grid the synth says which flags its compile
/// needs; for the 20 Hz sleeve (the compile's default) it says nothing more.
#[test]
fn a_synthetic_npy_of_the_grid_names_the_flags_its_compile_needs() {
    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("c.npy");
    let out = touchc(&["synth", "tap", "--sensor", "grid10", "-o", s(&npy)]);
    ok(&out);
    assert!(
        stderr(&out).contains("--rate 54 --pitch-mm 25.4"),
        "{}",
        stderr(&out)
    );
    assert!(std::fs::read(&npy).unwrap().starts_with(b"\x93NUMPY"));
    let out = touchc(&["synth", "tap", "-o", s(&npy)]);
    ok(&out);
    assert!(!stderr(&out).contains("--rate"), "{}", stderr(&out));
}
