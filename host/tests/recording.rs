//! Stage 0 input validation: every bad file is a typed error that names the file.

mod common;

use ndarray::{Array2, Array3, ShapeBuilder};
use ndarray_npy::WriteNpyExt;

use touchc::recording::{Recording, RecordingError};
use touchc::track::track;

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
fn rejects_other_dtypes() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "ints.npy", &Array3::<i64>::zeros((50, 2, 2)));
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
    assert!(matches!(load_err(&p), RecordingError::NotNpy { .. }));
    let truncated = dir.path().join("cut.npy");
    let full = write(&dir, "full.npy", &Array3::<f64>::zeros((50, 2, 2)));
    let bytes = std::fs::read(full).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 8]).unwrap();
    assert!(matches!(
        load_err(&truncated),
        RecordingError::NotNpy { .. }
    ));
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
        &touchc::config::Config::preset(touchc::config::Preset::Paper),
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
            &touchc::config::Config::preset(touchc::config::Preset::Paper)
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
    let cfg = touchc::config::Config::preset(touchc::config::Preset::Paper);
    let (t64, t32) = (track(&c64, &cfg).unwrap(), track(&c32, &cfg).unwrap());
    assert!(!t64.trajectories.is_empty());
    assert_eq!(t64, t32);
    assert_eq!(t64, track(&f64_, &cfg).unwrap());
}
