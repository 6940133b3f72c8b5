//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! The pipeline lives in one crate per layer under `host/crates/` (see
//! `docs/architecture.md`), each imported by its own name (`touchc_model`,
//! `touchc_tracking`, `touchc_pipeline`, ...). This package is the `touchc` command line
//! and its pictures and sound ([`viz`]). The library holds the pictures and sound, so
//! the command line's tests and the trade's SVG can draw without the argument parser,
//! and how the process returns freed memory ([`memory`]), so that the benchmarks
//! measure what the command line holds.

#![warn(missing_docs)]

pub mod memory;

#[cfg(feature = "viz")]
pub mod viz;
