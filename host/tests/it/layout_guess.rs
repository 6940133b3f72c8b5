//! A recording saved with time last (`[rows, cols, frames]`) compiles, but the compile
//! says which frames and grid it read, and that the shape reads better the other way.

use crate::bin::{ok, s, stderr, touchc};
use ndarray::Array3;
use touchc_input::sanity::transposed;
use touchc_input::warning::{InputWarning, TransposedBy};
use touchc_synth::{self as synth, SynthSpec};

fn compile(dir: &std::path::Path, name: &str, rec: &Array3<f64>) -> String {
    let path = dir.join(name);
    std::fs::write(&path, synth::to_npy(rec).unwrap()).unwrap();
    let out = touchc(&["compile", s(&path), "-o", s(&path.with_extension("touch"))]);
    ok(&out);
    stderr(&out)
}

/// The sleeve's stroke saved as `[8, 21, 144]`: the summary line names the frames
/// and grid read, and a warning says how to save it; the same recording the right
/// way round gets neither warning nor a wrong grid.
#[test]
fn a_recording_saved_time_last_is_named_with_the_grid_it_was_read_as() {
    let dir = tempfile::tempdir().unwrap();
    let right = synth::generate(&SynthSpec::default());
    let (t, r, c) = right.dim();
    let err = compile(dir.path(), "right.npy", &right);
    assert!(err.contains(&format!("{t} frames of {r} x {c}, ")), "{err}");
    assert!(!err.contains("warning"), "{err}");

    let mut wrong = right.clone();
    wrong.swap_axes(0, 1);
    wrong.swap_axes(1, 2); // [rows, cols, frames]
    let wrong = wrong.as_standard_layout().to_owned();
    assert_eq!(wrong.dim(), (r, c, t));
    let err = compile(dir.path(), "wrong.npy", &wrong);
    assert!(err.contains(&format!("{r} frames of {c} x {t}, ")), "{err}");
    let warning = err
        .lines()
        .find(|l| l.contains("warning") && l.contains("[rows, cols, frames]"));
    assert!(
        warning.is_some_and(|w| w.contains("np.moveaxis(a, -1, 0)")),
        "{err}"
    );
}

/// The shapes that read as time last, and ordinary recordings that must not.
#[test]
fn time_last_is_told_by_a_long_last_axis_or_the_sleeve_grid_first() {
    let is = |shape, reason| {
        assert_eq!(
            transposed(shape),
            Some(InputWarning::LikelyTransposed {
                shape: [shape.0, shape.1, shape.2],
                reason
            }),
            "{shape:?}"
        )
    };
    is((10, 10, 300), TransposedBy::LastAxisLongest);
    is((8, 21, 84), TransposedBy::LastAxisLongest);
    is((8, 21, 30), TransposedBy::SleeveGridFirst);
    for ordinary in [
        (84, 8, 21),
        (1, 8, 21),
        (10, 8, 21),
        (300, 10, 10),
        (5, 10, 10),
    ] {
        assert_eq!(transposed(ordinary), None, "{ordinary:?}");
    }
}
