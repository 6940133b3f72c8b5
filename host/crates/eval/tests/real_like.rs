//! The real-like cases (a fabric grid's touch, `touchc_synth::cases::real_like_on`)
//! under `touch` (contacts as regions): recalled and covered, about one trajectory per
//! true contact, and every one within its bar, bytes per second included, on both
//! sensors at both rates (seed 1; `touchc trade --cases --seeds 4` measures more
//! draws). Under format version 2's byte-coded keyframes four of the 20 Hz cases and
//! two of the 54 Hz ones failed on bytes alone; the bit-coded body of version 3
//! brought them within 150 B/s.
//!
//! About a second per case in a debug build.

use touchc_eval::cases::{run_case, CaseRow};
use touchc_model::config::{Preset, ValidConfig};
use touchc_pipeline::compile::CompileOptions;
use touchc_synth::cases::{real_like_on, Bar};
use touchc_synth::Sensor;

fn rows() -> Vec<CaseRow> {
    let configs = [(Preset::Touch, ValidConfig::preset(Preset::Touch))];
    [Sensor::Sleeve, Sensor::Grid10]
        .into_iter()
        .flat_map(|s| [20.0, 54.0].map(|hz| real_like_on(s, hz)))
        .flatten()
        .flat_map(|case| run_case(&case, 1, &CompileOptions::default(), &configs).unwrap())
        .collect()
}

#[test]
fn real_like_touch_is_one_trajectory_per_contact_and_within_its_bytes() {
    let rows = rows();
    assert_eq!(rows.len(), 32);
    for r in &rows {
        let what = format!("{} {} {} Hz: {r:?}", r.case, r.sensor, r.rate_hz);
        assert!(matches!(r.bar, Bar::RealLike { .. }), "{what}");
        assert!(r.passes(), "{what}");
    }
}
