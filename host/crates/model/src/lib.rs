//! The model every layer of `touchc` shares: the config with its presets, bounds and
//! validation ([`config`]), how a recording is sampled ([`config::Sampling`]), the
//! trajectories tracking hands on ([`trajectory`]), the active scene's window
//! ([`crop`]), the sleeve's actuator layout ([`layout`], [`geometry`]), the pipeline's
//! timed stages ([`stage`]) and the number formats messages use ([`display`]). It
//! imports no stage.

#![deny(missing_docs)]

pub mod config;
pub mod crop;
pub mod display;
pub mod geometry;
pub mod layout;
pub mod stage;
pub mod trajectory;
