//! Stage 7, encoding: the conditioned currents as keyframes in the stimulus file the
//! sleeve plays ([`keyframes`]).
//!
//! Hands on: the stimulus file's bytes (`touch_protocol`'s format).

#![deny(missing_docs)]

pub mod keyframes;
