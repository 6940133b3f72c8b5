//! The codes' CRC-32, the protocol's own (`touch_protocol::container`), streaming:
//! the same code hashes the codes on the host (build script) and on the target, so
//! the two can only agree if the codes do.

use touch_protocol::container::crc32_update;

/// Feeds `bytes` into a running CRC (start with `!0`, finish with `!crc`).
pub fn update(crc: u32, bytes: &[u8]) -> u32 {
    crc32_update(crc, bytes)
}

/// Feeds one frame of codes, little-endian.
pub fn update_frame(crc: u32, codes: &[u16; 8]) -> u32 {
    let mut bytes = [0u8; 16];
    for (b, c) in bytes.chunks_exact_mut(2).zip(codes) {
        b.copy_from_slice(&c.to_le_bytes());
    }
    update(crc, &bytes)
}
