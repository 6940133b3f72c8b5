//! Stages 1-3, tracking: from tared frames to the trajectories of the contacts.
//!
//! [`scene`] crops the active scene in time and space; [`preprocess`] upsamples and
//! blurs; [`detect`] finds the local maxima and their costs; [`track`] links them into
//! trajectories by min-cost flow ([`flow`]).
//!
//! Hands on: `trajectory::Trajectory`s in sensor cells at the upsampled frame rate.

#![deny(missing_docs)]

pub mod detect;
pub mod flow;
pub mod preprocess;
pub mod regions;
pub mod scene;
pub mod track;
