//! Stages 5-6, rendering to the actuators: each workspace's pressure signal from the
//! chosen trajectories ([`signals`]), then the currents the sleeve outputs, within its
//! safety limits ([`condition`]).
//!
//! Hands on: 8 currents in amperes at the 1 kHz output rate.

#![deny(missing_docs)]

pub mod condition;
pub mod signals;
