//! Stage 0 input validation: every bad file is a typed error that names the file.

use crate::common;
use crate::poison;

use ndarray::{Array2, Array3, ShapeBuilder};
use ndarray_npy::WriteNpyExt;

use touchc_input::recording::{Recording, RecordingError};
use touchc_pipeline::track::track;

fn write<T: WriteNpyExt>(dir: &tempfile::TempDir, name: &str, a: &T) -> std::path::PathBuf {
    let p = dir.path().join(name);
    a.write_npy(std::fs::File::create(&p).unwrap()).unwrap();
    p
}

fn load_err(p: &std::path::Path) -> RecordingError {
    let err = Recording::load(p).unwrap_err();
    assert!(
        err.to_string().contains(&p.display().to_string()),
        "message must name the file: {err}"
    );
    err
}

#[test]
fn reads_integers_as_counts_and_rejects_other_dtypes() {
    let dir = tempfile::tempdir().unwrap();
    let counts = Array3::<i16>::from_shape_fn((50, 2, 2), |(t, r, c)| (t + r + c) as i16);
    let p = write(&dir, "ints.npy", &counts);
    let rec = Recording::load(&p).unwrap();
    assert_eq!(rec.data()[[49, 1, 1]], 51.0);
    let p = write(
        &dir,
        "bools.npy",
        &Array3::<bool>::from_elem((50, 2, 2), true),
    );
    assert!(matches!(
        load_err(&p),
        RecordingError::UnsupportedDtype { .. }
    ));
}

#[test]
fn rejects_other_ranks() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "flat.npy", &Array2::<f64>::zeros((50, 2)));
    assert!(matches!(
        load_err(&p),
        RecordingError::WrongRank { ndim: 2, .. }
    ));
}

#[test]
fn rejects_empty_axes() {
    let dir = tempfile::tempdir().unwrap();
    for (i, shape) in [(0, 8, 21), (50, 0, 21), (50, 8, 0)]
        .into_iter()
        .enumerate()
    {
        let p = write(&dir, &format!("empty{i}.npy"), &Array3::<f64>::zeros(shape));
        assert!(matches!(load_err(&p), RecordingError::Empty { .. }));
    }
}

#[test]
fn rejects_all_nan() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        &dir,
        "nan.npy",
        &Array3::<f64>::from_elem((50, 8, 21), f64::NAN),
    );
    assert!(matches!(load_err(&p), RecordingError::AllNan { .. }));
}

#[test]
fn rejects_infinities_with_their_position() {
    let dir = tempfile::tempdir().unwrap();
    for v in [f64::INFINITY, f64::NEG_INFINITY] {
        let mut a = common::moving_blobs(60, 1, 3);
        a[[33, 4, 5]] = v;
        let p = write(&dir, "inf.npy", &a);
        match load_err(&p) {
            RecordingError::Infinite {
                frame, row, col, ..
            } => assert_eq!((frame, row, col), (33, 4, 5)),
            e => panic!("{e:?}"),
        }
    }
}

#[test]
fn rejects_files_that_are_not_npy_and_missing_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("notes.npy");
    std::fs::write(&p, "time,psi\n0,1.0\n").unwrap();
    assert!(matches!(load_err(&p), RecordingError::Text { .. }));
    std::fs::write(&p, b"\x00\x01binary").unwrap();
    assert!(matches!(load_err(&p), RecordingError::NotNpy { .. }));
    let truncated = dir.path().join("cut.npy");
    let full = write(&dir, "full.npy", &Array3::<f64>::zeros((50, 2, 2)));
    let bytes = std::fs::read(full).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 8]).unwrap();
    assert!(matches!(
        load_err(&truncated),
        RecordingError::Truncated {
            needed: 1600,
            found: 1592,
            ..
        }
    ));
    // Cut inside the header, and inside the preamble.
    for cut in [11, 9] {
        std::fs::write(&truncated, &bytes[..cut]).unwrap();
        assert!(matches!(
            load_err(&truncated),
            RecordingError::NotNpy { .. }
        ));
    }
    assert!(matches!(
        load_err(&dir.path().join("absent.npy")),
        RecordingError::Io { .. }
    ));
}

#[test]
fn too_short_for_the_tare_says_the_minimum() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "short.npy", &common::moving_blobs(40, 1, 1));
    let rec = Recording::load(&p).unwrap();
    let err = track(
        &rec,
        &touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper),
    )
    .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("short.npy") && msg.contains("at least 41 frames"),
        "{msg}"
    );
    let ok = Recording::load(write(&dir, "just.npy", &common::moving_blobs(41, 1, 1))).unwrap();
    assert_eq!(
        track(
            &ok,
            &touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper)
        )
        .unwrap()
        .frames()
        .dim()
        .0,
        1
    );
}

#[test]
fn fortran_order_and_f32_load_the_same_values() {
    let dir = tempfile::tempdir().unwrap();
    // f32-representable values, so the f32 file holds exactly the same numbers.
    let a = common::moving_blobs(80, 2, 5).mapv(|v| v as f32 as f64);
    let mut f = Array3::<f64>::zeros(a.dim().f());
    f.assign(&a);
    assert!(!f.is_standard_layout());
    let c64 = Recording::load(write(&dir, "c.npy", &a)).unwrap();
    let f64_ = Recording::load(write(&dir, "f.npy", &f)).unwrap();
    let c32 = Recording::load(write(&dir, "c32.npy", &a.mapv(|v| v as f32))).unwrap();
    let nan_eq = |x: &Recording, y: &Recording| {
        x.data()
            .iter()
            .zip(y.data().iter())
            .all(|(p, q)| p == q || (p.is_nan() && q.is_nan()))
    };
    assert!(nan_eq(&c64, &f64_) && nan_eq(&c64, &c32));
    let cfg = touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper);
    let (t64, t32) = (track(&c64, &cfg).unwrap(), track(&c32, &cfg).unwrap());
    assert!(!t64.trajectories.is_empty());
    assert_eq!(t64, t32);
    assert_eq!(t64, track(&f64_, &cfg).unwrap());
}

#[test]
fn every_poisoned_file_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, phrase) in poison::poisoned() {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let msg = load_err(&p).to_string();
        assert!(msg.contains(phrase), "{name}: {msg}");
    }
}

#[test]
fn the_shape_must_match_the_bytes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let body = poison::f64s((0..24).map(f64::from));
    let at = |name: &str, bytes: Vec<u8>| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let ok = Recording::load(at("ok.npy", poison::npy("<f8", false, "(4, 2, 3)", &body))).unwrap();
    assert_eq!(ok.dim(), (4, 2, 3));
    assert_eq!(ok.data()[[3, 1, 2]], 23.0);
    let short = at(
        "short.npy",
        poison::npy("<f8", false, "(4, 2, 3)", &body[..191]),
    );
    assert!(matches!(
        load_err(&short),
        RecordingError::Truncated {
            needed: 192,
            found: 191,
            ..
        }
    ));
    let long = at(
        "long.npy",
        poison::npy("<f8", false, "(4, 2, 3)", &[&body[..], &[0]].concat()),
    );
    assert!(matches!(
        load_err(&long),
        RecordingError::TrailingBytes {
            needed: 192,
            found: 193,
            ..
        }
    ));
    // A float32 header over float64 data is a size mismatch, not a reinterpretation.
    let f4 = at("f4.npy", poison::npy("<f4", false, "(4, 2, 3)", &body));
    assert!(matches!(
        load_err(&f4),
        RecordingError::TrailingBytes { .. }
    ));
    for descr in ["<c16", "|O", "<U3", "|b1", "<f2", "<M8[ns]"] {
        let p = at("odd.npy", poison::npy(descr, false, "(4, 2, 3)", &body));
        match load_err(&p) {
            RecordingError::UnsupportedDtype { descr: d, .. } => assert_eq!(d, descr),
            e => panic!("{descr}: {e}"),
        }
    }
    // A header that says more than numpy's three keys, or says them in Python that is
    // not a plain literal, is not read.
    for header in [
        "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 2, 3), 'extra': 1}",
        "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 2, 3)} # comment",
        "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 2, 2 + 1)}",
        "{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (4, 2, 3)}",
    ] {
        let p = at("odd.npy", poison::npy_raw(header, &body));
        assert!(
            matches!(load_err(&p), RecordingError::NotNpy { .. }),
            "{header}"
        );
    }
}

#[test]
fn big_endian_and_version_2_load_the_same_values() {
    let dir = tempfile::tempdir().unwrap();
    let a = common::moving_blobs(60, 1, 7).mapv(|v| v as f32 as f64);
    let le = Recording::load(write(&dir, "le.npy", &a)).unwrap();
    let shape = "(60, 8, 21)";
    let be8: Vec<u8> = a.iter().flat_map(|v| v.to_be_bytes()).collect();
    let be4: Vec<u8> = a.iter().flat_map(|&v| (v as f32).to_be_bytes()).collect();
    let mut v2 = poison::npy("<f8", false, shape, &poison::f64s(a.iter().copied()));
    // Version 2.0: a four-byte header length.
    let hlen = u16::from_le_bytes([v2[8], v2[9]]);
    v2.splice(6..10, [2, 0, hlen as u8, (hlen >> 8) as u8, 0, 0]);
    for (name, bytes) in [
        ("be8.npy", poison::npy(">f8", false, shape, &be8)),
        ("be4.npy", poison::npy(">f4", false, shape, &be4)),
        ("v2.npy", v2),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let r = Recording::load(&p).unwrap();
        let same = r
            .data()
            .iter()
            .zip(le.data().iter())
            .all(|(p, q)| p == q || (p.is_nan() && q.is_nan()));
        assert!(same, "{name}");
        assert_eq!(r.file_rate_hz(), None);
    }
}

/// The fixtures of `data/npz/make.py`, written by Python's zipfile as numpy.savez
/// calls it.
fn fixture(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/npz")
        .join(name)
}

#[test]
fn reads_savez_and_savez_compressed_archives_with_their_metadata() {
    let expected = |t: usize, r: usize, c: usize| -> f64 {
        if (r, c) == (0, 0) {
            f64::NAN
        } else {
            f64::from((t as f64 + r as f64 / 10.0 + c as f64 / 100.0) as f32)
        }
    };
    for (file, rate, pitch) in [
        ("savez.npz", Some(54.0), Some(25.0)),
        ("savez_compressed.npz", Some(54.0), None),
        ("streamed.npz", None, Some(8.5)),
    ] {
        let rec = Recording::load(fixture(file)).unwrap();
        assert_eq!(rec.dim(), (45, 3, 4), "{file}");
        for ((t, r, c), &v) in rec.data().indexed_iter() {
            let e = expected(t, r, c);
            assert!(v == e || (v.is_nan() && e.is_nan()), "{file} {t} {r} {c}");
        }
        assert_eq!(rec.file_rate_hz(), rate, "{file}");
        assert_eq!(rec.file_pitch_mm(), pitch, "{file}");
        assert!(rec.name().ends_with(file));
    }
}

#[test]
fn the_format_is_told_by_the_content_not_the_name() {
    let dir = tempfile::tempdir().unwrap();
    let npz = dir.path().join("really_a_zip.npy");
    std::fs::copy(fixture("savez.npz"), &npz).unwrap();
    assert_eq!(Recording::load(&npz).unwrap().file_rate_hz(), Some(54.0));
    let npy = dir.path().join("really_npy.npz");
    std::fs::write(&npy, poison::small_npy(5, 1.0)).unwrap();
    let rec = Recording::load(&npy).unwrap();
    assert_eq!((rec.dim(), rec.file_rate_hz()), ((5, 2, 3), None));
}

fn npz_with(
    dir: &tempfile::TempDir,
    name: &str,
    extra: Vec<poison::Entry<'_>>,
) -> std::path::PathBuf {
    let mut entries = vec![poison::Entry::deflated(
        "pressure.npy",
        poison::small_npy(6, 1.0),
    )];
    entries.extend(extra);
    let p = dir.path().join(name);
    std::fs::write(&p, poison::zip(&entries)).unwrap();
    p
}

#[test]
fn metadata_of_any_number_type_is_read() {
    let dir = tempfile::tempdir().unwrap();
    for (descr, body, value) in [
        ("<f4", 20.5f32.to_le_bytes().to_vec(), 20.5),
        (">f8", 1000.0f64.to_be_bytes().to_vec(), 1000.0),
        ("<f2", 0x4d00u16.to_le_bytes().to_vec(), 20.0),
        ("|u1", vec![200], 200.0),
        ("|i1", vec![100], 100.0),
        ("<i2", 54i16.to_le_bytes().to_vec(), 54.0),
        (">u4", 60u32.to_be_bytes().to_vec(), 60.0),
        ("<i8", 20i64.to_le_bytes().to_vec(), 20.0),
    ] {
        let p = npz_with(
            &dir,
            "m.npz",
            vec![poison::Entry::stored(
                "rate_hz.npy",
                poison::scalar_npy(descr, &body),
            )],
        );
        assert_eq!(
            Recording::load(&p).unwrap().file_rate_hz(),
            Some(value),
            "{descr}"
        );
    }
    // One element in any shape is one number; an entry named without `.npy` counts.
    let p = npz_with(
        &dir,
        "m.npz",
        vec![poison::Entry::stored(
            "pitch_mm",
            poison::npy("<f8", false, "(1, 1)", &2.5f64.to_le_bytes()),
        )],
    );
    assert_eq!(Recording::load(&p).unwrap().file_pitch_mm(), Some(2.5));
}

#[test]
fn metadata_out_of_range_names_the_file_the_field_the_value_and_the_range() {
    let dir = tempfile::tempdir().unwrap();
    for (field, value, range) in [
        ("rate_hz", 0.0, "1 to 1000 Hz"),
        ("rate_hz", -20.0, "1 to 1000 Hz"),
        ("rate_hz", f64::NAN, "1 to 1000 Hz"),
        ("rate_hz", f64::INFINITY, "1 to 1000 Hz"),
        ("rate_hz", 54000.0, "1 to 1000 Hz"),
        ("pitch_mm", 0.0, "0.1 to 100 mm"),
        ("pitch_mm", 254.0, "0.1 to 100 mm"),
    ] {
        let entry = format!("{field}.npy");
        let p = npz_with(
            &dir,
            "bad_meta.npz",
            vec![poison::Entry::stored(
                &entry,
                poison::scalar_npy("<f8", &value.to_le_bytes()),
            )],
        );
        let err = load_err(&p);
        assert!(matches!(err, RecordingError::MetadataRange { .. }), "{err}");
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("{field} = {value}")) && msg.contains(range),
            "{msg}"
        );
    }
    for (descr, shape, body, found) in [
        ("<U3", "()", vec![0; 12], "element type <U3"),
        ("<f8", "(2,)", vec![0; 16], "shape (2,) of <f8"),
        ("<f8", "(0,)", vec![], "shape (0,) of <f8"),
        ("<c16", "()", vec![0; 16], "element type <c16"),
    ] {
        let p = npz_with(
            &dir,
            "odd_meta.npz",
            vec![poison::Entry::stored(
                "rate_hz.npy",
                poison::npy(descr, false, shape, &body),
            )],
        );
        let msg = load_err(&p).to_string();
        assert!(
            msg.contains("rate_hz must be a single number") && msg.contains(found),
            "{msg}"
        );
    }
}

#[test]
fn archive_entries_are_checked_like_files() {
    let dir = tempfile::tempdir().unwrap();
    let at = |name: &str, entries: &[poison::Entry<'_>]| {
        let p = dir.path().join(name);
        std::fs::write(&p, poison::zip(entries)).unwrap();
        p
    };
    // The whole chain of .npy checks applies inside, and the message names the entry.
    let p = at(
        "rank2.npz",
        &[poison::Entry::stored(
            "pressure.npy",
            poison::npy("<f8", false, "(3, 2)", &[0; 48]),
        )],
    );
    let msg = load_err(&p).to_string();
    assert!(
        msg.contains("entry \"pressure.npy\"") && msg.contains("found 2 dimension"),
        "{msg}"
    );
    let p = at(
        "nan.npz",
        &[poison::Entry::deflated(
            "pressure.npy",
            poison::npy("<f8", false, "(2, 2, 3)", &poison::f64s([f64::NAN; 12])),
        )],
    );
    assert!(matches!(load_err(&p), RecordingError::AllNan { .. }));
    // An entry shorter than it says, honestly declared: truncated.
    let short = poison::npy("<f8", false, "(2, 2, 3)", &[0; 40]);
    let p = at(
        "short.npz",
        &[poison::Entry::stored("pressure.npy", short.clone())],
    );
    assert!(matches!(load_err(&p), RecordingError::EntrySize { .. }));
    // The same, declaring the size its header needs: the data that is there is short.
    let p = at(
        "short.npz",
        &[poison::Entry {
            declared: Some(short.len() as u32 + 56),
            ..poison::Entry::stored("pressure.npy", short)
        }],
    );
    assert!(
        matches!(
            load_err(&p),
            RecordingError::Truncated {
                needed: 96,
                found: 40,
                ..
            }
        ),
        "{}",
        load_err(&p)
    );
    // A corrupted payload fails the checksum.
    let mut bytes = poison::zip(&[poison::Entry::stored(
        "pressure.npy",
        poison::small_npy(6, 1.0),
    )]);
    let data_at = 30 + "pressure.npy".len() + 140;
    bytes[data_at] ^= 1;
    let p = dir.path().join("crc.npz");
    std::fs::write(&p, bytes).unwrap();
    let msg = load_err(&p).to_string();
    assert!(msg.contains("not a readable .npz"), "{msg}");
    // An archive cut short, and an empty one.
    let whole = std::fs::read(fixture("savez_compressed.npz")).unwrap();
    let p = dir.path().join("cut.npz");
    std::fs::write(&p, &whole[..whole.len() / 2]).unwrap();
    assert!(matches!(load_err(&p), RecordingError::NotNpz { .. }));
    let p = at("empty.npz", &[]);
    let msg = load_err(&p).to_string();
    assert!(
        msg.contains("no array named 'pressure'") && msg.contains("no entries"),
        "{msg}"
    );
}
