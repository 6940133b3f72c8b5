//! The one driver of `touchc`'s stages: [`compile`] runs stages 0-7 in order on the
//! active scene, timing each [`Stage`](touchc_model::stage::Stage) and measuring how much
//! of the touch the placement kept ([`coverage`]) and how much of it the sleeve plays
//! ([`rendered`]); [`track`] runs stages 0-3 alone, as
//! `touchc track` does.

#![deny(missing_docs)]

pub mod compile;
pub mod coverage;
pub mod rendered;
pub mod track;
