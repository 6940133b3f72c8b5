//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! One module per pipeline stage, in data-flow order:
//!
//! | stage | module | hands on |
//! |---|---|---|
//! | 0 load, tare | [`recording`] | tared frames |
//! | 1 upsample, blur | [`preprocess`] | blurred frames, mean, std |
//! | 2 detections | [`detect`] | detections with costs |
//! | 3 trajectories | [`track`] (on [`flow`]) | [`trajectory::Trajectory`] |
//! | 4 placement | [`placement`] (on [`layout`], [`bnb`]) | circles, chosen trajectories |
//! | 5 actuator signals | [`signals`] | 8 pressures at the frame rate |
//! | 6 conditioning | [`condition`] | 8 currents at 1 kHz |
//! | 7 keyframes | [`keyframes`] | the stimulus file |
//!
//! [`compile`] runs them in order on the active scene ([`scene`]); [`trade`] measures
//! the presets of [`config::Preset`] against each other.

pub mod config;
pub mod geometry;
pub mod trajectory;

pub mod recording;
pub mod preprocess;
pub mod detect;
pub mod flow;
pub mod track;

pub mod layout;
pub mod bnb;
pub mod placement;

pub mod signals;
pub mod condition;
pub mod keyframes;

pub mod scene;
pub mod sanity;
pub mod compile;
pub mod coverage;
pub mod evaluate;
pub mod trade;

pub mod output;
pub mod synth;
pub mod viz;
