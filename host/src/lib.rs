//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! The pipeline lives in one crate per layer under `host/crates/` (see
//! `docs/architecture.md`), each imported by its own name (`touchc_model`,
//! `touchc_tracking`, `touchc_pipeline`, ...). This package is the `touchc` command line
//! and its pictures and sound ([`viz`]); the library holds only the latter, so the
//! command line's tests and the trade's SVG can draw without the argument parser.

#![warn(missing_docs)]

#[cfg(feature = "viz")]
pub mod viz;
