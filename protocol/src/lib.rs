//! Wire formats and the fixed-point player shared by the `touchc` compiler and the
//! sleeve firmware.
//!
//! - [`stimulus`]: one haptic pattern, keyframed, with its safety limits.
//! - [`bank`]: several stimuli, one per button slot, as one flash image.
//! - [`player`]: turns a stimulus into eight 12-bit output codes per 1 kHz tick.
//! - [`thermal`]: the coils' heat, which the device keeps across plays.
//! - [`layout`]: the actuator layout's identity, a hash of its geometry.
//!
//! Both files are framed the same way (magic, version, length, CRC-32; see
//! [`container`]) and `SPEC.md` describes every byte. The crate is `no_std` and
//! allocation-free; the `std` feature adds the encoders, `defmt` adds log formats.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]

pub mod bank;
pub mod container;
mod error;
pub mod layout;
mod limits;
pub mod player;
pub mod stimulus;
pub mod thermal;

pub use bank::Bank;
pub use error::Error;
pub use limits::Limits;
pub use player::{DeviceConfig, OutputSink, Player, Status, Tick};
pub use stimulus::Stimulus;
pub use thermal::Thermal;

/// Output channels: 2 rows x 4 columns of actuators, `channel = row * 4 + column`.
pub const CHANNELS: usize = 8;

/// The code for 0 A on a 12-bit output (mid-scale).
pub const IDLE_CODE: u16 = 2048;
