//! The link to a computer (USB or a USART, the same frames): the server that answers
//! requests, the queues that connect it to the 1 kHz tick, and the bank writer.
//!
//! - [`server`]: frames in, replies and events out ([`LinkServer`]).
//! - [`port`]: the lock-free queues between the server and the tick's
//!   [`crate::control::Controller`] ([`Channels`]).
//! - [`bank`]: a new bank into flash, safe against a power cut at any byte.
pub mod bank;
pub mod port;
pub mod server;
#[cfg(any(test, feature = "sim"))]
pub mod sim;

pub use port::{Answer, Channels, Control, LinkPort, Snapshot, TickPort};
pub use server::{Identity, LinkServer};

#[cfg(test)]
mod tests;
