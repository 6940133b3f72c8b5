//! Stage 0, the input: a recording loaded from disk and tared ([`recording`]), the
//! warnings for recordings that compile but probably mean something else ([`sanity`]),
//! and synthetic recordings with their truth for running the chain without a sleeve
//! ([`synth`]).
//!
//! Hands on: tared frames `[T, rows, cols]` in psi at the sensor rate, NaN = no cell.

#![deny(missing_docs)]

pub mod recording;
pub mod sanity;
pub mod synth;
pub mod warning;
