//! Fixtures shared by `touchc`'s integration tests, benches, examples and fuzz
//! targets, so each is written once:
//!
//! - [`recordings`]: synthetic recordings (moving blobs, the compile bench's
//!   combination, the real-touch cases) and a CPU clock for the benches.
//! - [`mod@reference`]: the published Python code's reference vectors and their loader.
//! - [`rng`]: the one seeded generator of the tests (`touchc-test-rng`, which the
//!   layers' unit tests use directly).
//! - [`stimuli`]: stimulus files for the tests that drive the CLI.
//! - [`fuzz_input`]: the compile fuzz target's recordings, built from its bytes.
//! - [`poison`]: hand-built `.npy` and `.npz` files, most of them wrong in one way.
//! - [`bin`]: running the real `touchc` binary.
//!
//! The recordings, the reference loader and the generator also stand at the crate's
//! root, which the tests, benches and examples name `common`.
#![warn(missing_docs)]

pub mod bin;
pub mod fuzz_input;
pub mod poison;
pub mod recordings;
pub mod reference;
pub mod stimuli;

pub use recordings::{combination_698, cpu_seconds, moving_blobs, sleeve_mask, touch_cases};
pub use reference::{reference_dir, RefTrajectory, Reference};
pub use touchc_test_rng::{self as rng, Xorshift};
