//! CRC-32 (IEEE, reflected), bitwise and streaming: the same code hashes the codes on
//! the host (build script) and on the target, so the two can only agree if the
//! codes do.

/// Feeds `bytes` into a running CRC (start with `!0`, finish with `!crc`).
pub fn update(mut crc: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    crc
}

/// Feeds one frame of codes, little-endian.
pub fn update_frame(mut crc: u32, codes: &[u16; 8]) -> u32 {
    for c in codes {
        crc = update(crc, &c.to_le_bytes());
    }
    crc
}
