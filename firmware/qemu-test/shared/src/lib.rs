//! What the QEMU test's two sides share: the build script computes the expected
//! codes on the host, the binary checks them on the target, and both must hash them
//! and press the button alike. A crate of its own so that both depend on it (a build
//! script cannot use its own package's code).
#![no_std]

pub mod crc32;
pub mod scenario;
