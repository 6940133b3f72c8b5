//! The compile fuzz target's recordings, built from its bytes: shared by the target
//! (`host/fuzz/fuzz_targets/compile.rs`) and the tests that replay its seeds.
//!
//! Bytes `t, r, c, scale, cells...`: up to 100 frames of up to 6 x 6 cells (the default
//! tare needs 41), each cell's value a byte times a step of 1e-8 to 1e7 psi, 0xff = NaN,
//! missing bytes 0.

use ndarray::Array3;

/// The recording the compile target builds from `data`; `None` when `data` is shorter
/// than its four leading bytes.
pub fn recording(data: &[u8]) -> Option<Array3<f64>> {
    let [t, r, c, scale, cells @ ..] = data else {
        return None;
    };
    let dim = (
        1 + usize::from(*t) % 100,
        1 + usize::from(*r) % 6,
        1 + usize::from(*c) % 6,
    );
    let step = 10f64.powi(i32::from(*scale % 16) - 8);
    let n = dim.0 * dim.1 * dim.2;
    let values = (0..n)
        .map(|i| match cells.get(i) {
            Some(0xff) => f64::NAN,
            Some(&b) => f64::from(b) * step,
            None => 0.0,
        })
        .collect();
    Array3::from_shape_vec(dim, values).ok()
}
