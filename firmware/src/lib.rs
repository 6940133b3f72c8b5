//! The sleeve firmware's logic, free of hardware so it runs on the host too.
//!
//! The data flow, top to bottom:
//! - [`boot`]: is the bank in flash usable? If not, which LED code says why.
//! - [`button`]: EXTI edges -> debounced levels -> gestures (press, long press).
//! - [`control`]: gestures -> which slot plays; steps the [`touch_protocol::Player`]
//!   (with the link, one the link's task built ahead, see [`link::port`]).
//! - [`engine`]: the 1 kHz tick: write the frame computed last tick, then compute
//!   the next one.
//! - [`output`]: codes -> timer compare values; the compiled hard limits.
//! - [`led`]: what the status LED shows, as patterns a person tells apart.
//! - [`link`]: the computer's link: requests in, replies and events out, the bank
//!   writer.
//!
//! The binary (`src/main.rs`, target only) wires these to TIM3/TIM4/DAC, TIM7,
//! EXTI and the watchdog.
#![cfg_attr(not(any(test, feature = "sim", feature = "testutil")), no_std)]
#![warn(missing_docs)]

pub mod boot;
pub mod button;
pub mod control;
pub mod engine;
pub mod led;
pub mod link;
pub mod output;

#[cfg(any(test, feature = "testutil"))]
pub mod testutil;
