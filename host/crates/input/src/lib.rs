//! Stage 0, the input: a recording loaded from disk and tared ([`recording`]), and the
//! warnings for recordings that compile but probably mean something else ([`sanity`]).
//! Synthetic recordings live in their own crate, `touchc-synth`, which nothing in the
//! pipeline depends on.
//!
//! Hands on: tared frames `[T, rows, cols]` in psi at the sensor rate, NaN = no cell.

#![deny(missing_docs)]

pub mod recording;
pub mod sanity;
pub mod warning;
