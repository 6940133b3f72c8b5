//! Any bytes as a recording file (`.npy` or `.npz`, told by the content): loading
//! returns a recording or an error naming the file, never panics, and never holds more
//! values than the bytes can carry (deflate expands at most 1032:1).
#![no_main]

use libfuzzer_sys::fuzz_target;
use touchc_model::config::{PITCH_MM_RANGE, RATE_HZ_RANGE};
use touchc_input::recording::Recording;
use touchc_testkit::poison::{self, Entry};

fuzz_target!(|data: &[u8]| {
    check(data);
    // Inside an archive too, without the fuzzer having to find the zip structure
    // first: the bytes as the pressure entry, stored and deflated, and as a metadata
    // entry beside a valid pressure array.
    check(&poison::zip(&[Entry::stored("pressure.npy", data.to_vec())]));
    check(&poison::zip(&[Entry::deflated("pressure.npy", data.to_vec())]));
    check(&poison::zip(&[
        Entry::stored("pressure.npy", poison::small_npy(3, 1.0)),
        Entry::stored("rate_hz.npy", data.to_vec()),
    ]));
});

fn check(bytes: &[u8]) {
    match Recording::from_bytes("fuzz.in", bytes) {
        Ok(rec) => {
            let (t, r, c) = rec.dim();
            assert!(t > 0 && r > 0 && c > 0);
            assert!(rec.data().len() <= bytes.len().saturating_mul(1032));
            assert!(rec.data().iter().all(|v| !v.is_infinite()));
            assert!(rec.data().iter().any(|v| !v.is_nan()));
            assert!(rec.file_rate_hz().is_none_or(|v| RATE_HZ_RANGE.contains(&v)));
            assert!(rec.file_pitch_mm().is_none_or(|v| PITCH_MM_RANGE.contains(&v)));
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.in"), "{e}"),
    }
}
