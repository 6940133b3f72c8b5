//! The link to a sleeve: the firmware's link protocol ([`touch_protocol::link`])
//! spoken from the host, over a serial port or any other byte stream.
//!
//! - [`Transport`]: a byte stream with read timeouts; [`MemoryTransport`] is an
//!   in-memory pair for tests, [`serial::SerialTransport`] a serial port (the
//!   sleeve's USB socket or a USB-serial adapter on its USART).
//! - [`Client`]: requests and their replies, events, upload and stream.
//!
//! Pure Rust: no libusb, no libudev (ports are found through sysfs on Linux).

#![deny(missing_docs)]

mod client;
pub mod serial;
mod transport;

pub use client::{
    Client, ClientError, DeviceInfo, Progress, SlotEntry, Stamped, Started, Timeouts, VerifyError,
};
pub use transport::{MemoryTransport, Transport};
