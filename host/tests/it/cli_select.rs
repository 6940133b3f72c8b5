//! `touchc select` on the real binary: labelled synthetic data sets in folders and
//! manifests, both scorers, the outputs, a saved model, and the data sets it refuses.

use std::collections::BTreeMap;
use std::path::Path;

use crate::bin;
use bin::{command, ok, s, touchc};
use touchc_select::synthetic::{labelled_set, write, Mix, SetSpec};
use touchc_synth::Sensor;

/// A data set of `classes` x `per_class` recordings by 6 people in `dir`.
fn data_set(dir: &Path, classes: usize, per_class: usize) {
    let set = labelled_set(&SetSpec {
        classes,
        per_class,
        people: 6,
        sensor: Sensor::Sleeve,
        frames: None,
        mix: Mix::Separable,
        seed: 4,
    });
    write(dir, &set).unwrap();
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Runs `touchc select ARGS` and expects exit status `code`, an error naming `what`,
/// and no output directory.
fn refused_with(args: &[&str], code: i32, what: &str, out: &Path) {
    let o = touchc(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "{err}");
    assert!(err.contains(what), "{what:?} not in {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "partial output left in {}", out.display());
}

#[test]
fn features_learn_separable_classes_with_grouped_folds_that_keep_people_whole() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    data_set(&data, 6, 18);
    let out = dir.path().join("sel");
    let manifest = data.join("manifest.csv");
    let o = touchc(&["select", s(&manifest), "--top", "3", "-o", s(&out)]);
    ok(&o);
    let report = json(&out.join("report.json"));
    assert_eq!(report["grouped"], true);
    assert_eq!(report["classes"].as_array().unwrap().len(), 6);
    // Chance is 1/6.
    assert!(report["accuracy"].as_f64().unwrap() > 0.6, "{report}");
    assert!(report["macro_f1"].as_f64().unwrap() > 0.5, "{report}");
    let confusion: Vec<Vec<u64>> = serde_json::from_value(report["confusion"].clone()).unwrap();
    assert_eq!(confusion.iter().flatten().sum::<u64>(), 108);
    assert!(report["seconds"].as_f64().unwrap() > 0.0);
    // scores.csv: one row per recording; each person's rows in one fold.
    let csv = std::fs::read_to_string(out.join("scores.csv")).unwrap();
    let mut fold_of: BTreeMap<String, String> = BTreeMap::new();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 108);
    for row in rows {
        let f: Vec<&str> = row.split(',').collect();
        let (group, fold) = (f[2].to_string(), f[3].to_string());
        assert_eq!(
            fold_of.entry(group.clone()).or_insert(fold.clone()),
            &fold,
            "{group} split"
        );
        let total: f64 = f[5..].iter().map(|v| v.parse::<f64>().unwrap()).sum();
        assert!((total - 1.0).abs() < 1e-4, "{row}");
    }
    assert!(String::from_utf8_lossy(&o.stdout).contains("accuracy"));
}

#[test]
fn the_network_learns_and_scores_the_same_for_a_seed_whatever_the_threads() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    data_set(&data, 3, 10);
    let run = |out: &str, threads: &str| {
        let out = dir.path().join(out);
        let o = command()
            .args([
                "select",
                s(&data),
                "--model",
                "cnn",
                "--folds",
                "3",
                "--epochs",
                "30",
            ])
            .args(["--seed", "3", "-o", s(&out)])
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        ok(&o);
        (
            std::fs::read(out.join("scores.csv")).unwrap(),
            json(&out.join("report.json")),
        )
    };
    let (a, report) = run("a", "1");
    let (b, _) = run("b", "2");
    assert_eq!(a, b, "scores differ between 1 and 2 threads");
    assert_eq!(report["scorer"], "cnn");
    assert_eq!(report["grouped"], false);
    // Chance is 1/3.
    assert!(report["accuracy"].as_f64().unwrap() > 0.5, "{report}");
}

#[test]
fn compile_writes_a_bank_that_inspect_accepts_and_a_saved_model_scores_new_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    data_set(&data, 3, 8);
    let out = dir.path().join("sel");
    let model = dir.path().join("m.json");
    let o = touchc(&[
        "select",
        s(&data),
        "--folds",
        "4",
        "--compile",
        "-o",
        s(&out),
        "--model-file",
        s(&model),
    ]);
    ok(&o);
    ok(&touchc(&["inspect", s(&out.join("bank.bin"))]));
    for class in ["attention", "calming", "gratitude"] {
        assert!(out.join(format!("{class}.touch")).is_file());
    }
    // Each class's best two: six slots, class by class, best first.
    let two = dir.path().join("two");
    let o = touchc(&[
        "select",
        s(&data),
        "--folds",
        "4",
        "--top",
        "3",
        "--compile",
        "--compile-top",
        "2",
        "-o",
        s(&two),
    ]);
    ok(&o);
    let o = touchc(&["inspect", s(&two.join("bank.bin"))]);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("slot 5: ") && !text.contains("slot 6: "),
        "{text}"
    );
    let (first, second) = (text.find("attention").unwrap(), text.find("attention_2"));
    assert!(second.is_some_and(|at| at > first), "{text}");
    for class in ["attention", "calming", "gratitude"] {
        assert!(two.join(format!("{class}_2.touch")).is_file());
        assert!(!two.join(format!("{class}_3.touch")).exists());
    }
    // More than --top lists, none, or more than a bank's 32 slots: usage errors.
    let many = dir.path().join("many");
    for (k, top, what) in [
        ("4", "3", "more than the 3 listed"),
        ("0", "3", "at least one"),
        ("11", "11", "3 classes x 11 = 33 stimuli"),
    ] {
        let args = [
            "select",
            s(&data),
            "--top",
            top,
            "--compile",
            "--compile-top",
            k,
            "-o",
            s(&many),
        ];
        refused_with(&args, 2, what, &many);
    }
    let new = data.join("calming/calming_0008.npy");
    let o = touchc(&["select", "--model-file", s(&model), "--score", s(&new)]);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("path,best,attention,calming,gratitude"));
    let row = lines.next().unwrap();
    assert!(row.contains(",calming,"), "{row}");
    // A file that is not a model.
    let o = touchc(&["select", "--model-file", s(&new), "--score", s(&new)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a model file"));
}

#[test]
fn bad_data_sets_are_refused_with_the_file_named_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sel");
    // One class.
    let one = dir.path().join("one");
    data_set(&one, 2, 6);
    std::fs::remove_dir_all(one.join("calming")).unwrap();
    refused_with(&["select", s(&one), "-o", s(&out)], 1, "1 class(es)", &out);
    // An empty class.
    let empty = dir.path().join("empty");
    data_set(&empty, 2, 6);
    std::fs::create_dir(empty.join("love")).unwrap();
    refused_with(
        &["select", s(&empty), "-o", s(&out)],
        1,
        "\"love\" has no recording",
        &out,
    );
    // Mixed sensor shapes.
    let mixed = dir.path().join("mixed");
    data_set(&mixed, 2, 6);
    let grid = labelled_set(&SetSpec {
        classes: 2,
        per_class: 1,
        people: 1,
        sensor: Sensor::Grid10,
        frames: None,
        mix: Mix::Separable,
        seed: 1,
    });
    let odd = mixed.join("calming/zz_grid.npy");
    std::fs::write(&odd, touchc_synth::to_npy(&grid[0].frames).unwrap()).unwrap();
    refused_with(
        &["select", s(&mixed), "-o", s(&out)],
        1,
        "zz_grid.npy: frames of 10 x 10",
        &out,
    );
    // A corrupt file.
    let corrupt = dir.path().join("corrupt");
    data_set(&corrupt, 2, 6);
    let bad = corrupt.join("attention/bad.npy");
    std::fs::write(&bad, b"\x93NUMPY garbage").unwrap();
    refused_with(&["select", s(&corrupt), "-o", s(&out)], 1, "bad.npy", &out);
    // A manifest line without a label; too few folds (usage).
    let manifest = dir.path().join("m.csv");
    std::fs::write(&manifest, "path,label\nonly_a_path\n").unwrap();
    refused_with(
        &["select", s(&manifest), "-o", s(&out)],
        1,
        "m.csv: line 2",
        &out,
    );
    refused_with(
        &["select", s(&corrupt), "--folds", "1", "-o", s(&out)],
        2,
        "--folds 1",
        &out,
    );
}

#[test]
fn ctrl_c_stops_training_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    data_set(&data, 2, 8);
    let out = dir.path().join("sel");
    let model = dir.path().join("m.json");
    let child = command()
        .args([
            "select",
            s(&data),
            "--model",
            "cnn",
            "--epochs",
            "100000",
            "-o",
            s(&out),
        ])
        .args(["--model-file", s(&model)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(3000));
    let status = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted: nothing written"), "{err}");
    assert!(!out.exists() && !model.exists());
}
