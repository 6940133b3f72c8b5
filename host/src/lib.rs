//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! One module per pipeline stage, in data-flow order.

pub mod config;
pub mod geometry;
pub mod output;
pub mod trajectory;
