//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! One folder per step of the pipeline, in data-flow order:
//!
//! | stage | module | hands on |
//! |---|---|---|
//! | 0 load, tare | [`input`] ([`input::recording`]) | tared frames |
//! | 1 crop, upsample, blur (streamed) | [`tracking`] ([`tracking::scene`], the driver of 1-3; [`tracking::preprocess`]) | each blurred frame in turn, mean, std |
//! | 2 detections | [`tracking::detect`] | detections with costs |
//! | 3 trajectories | [`tracking::track`] (on [`tracking::flow`]) | [`tracking::trajectory::Trajectory`] |
//! | 4 placement | [`placement`] (on [`placement::layout`], [`placement::bnb`]) | circles, chosen trajectories |
//! | 5 actuator signals | [`rendering::signals`] | 8 pressures at the frame rate |
//! | 6 conditioning | [`rendering::condition`] | 8 currents at 1 kHz |
//! | 7 keyframes | [`encoding::keyframes`] | the stimulus file |
//!
//! [`compile`] runs them in order on the active scene, timing each [`stage::Stage`]; [`measure`] says how much of the
//! touch a compile kept ([`measure::coverage`], [`measure::evaluate`]) and measures the
//! presets of [`config::Preset`] against each other ([`measure::trade`]).

#![warn(missing_docs)]

pub mod config;
pub mod display;
pub mod geometry;

pub mod input;
pub mod tracking;
pub mod placement;
pub mod rendering;
pub mod encoding;
pub mod export;

pub mod compile;
pub mod track;
pub mod stage;
pub mod measure;

mod wide;

#[cfg(test)]
mod test_rng;

#[cfg(feature = "viz")]
pub mod viz;

#[cfg(feature = "link")]
pub mod link;
