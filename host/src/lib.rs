//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! One module per pipeline stage, in data-flow order.

pub mod bnb;
pub mod config;
pub mod geometry;
pub mod layout;
pub mod placement;
pub mod trajectory;

pub mod condition;
pub mod keyframes;
pub mod signals;

pub mod output;
pub mod synth;
pub mod viz;
