//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! One module per pipeline stage, in data-flow order.

pub mod config;
pub mod geometry;
pub mod trajectory;

pub mod detect;
pub mod flow;
pub mod preprocess;
pub mod recording;
pub mod track;
