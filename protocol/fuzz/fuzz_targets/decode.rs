//! Any bytes, as a stimulus and as a bank: decoding returns `Ok` or an error and
//! never panics; whatever decodes also plays to the end within its stated length.
#![no_main]

use libfuzzer_sys::fuzz_target;
use touch_protocol::{Bank, DeviceConfig, Player, Stimulus};

fn play(s: &Stimulus<'_>) {
    let mut p = Player::new(s, &DeviceConfig::default());
    // Signal, ramp, and a slew-limited tail of at most peak / slew ticks.
    let bound = u64::from(s.header().playback_ms()) + 1 + 2_000;
    let mut n = 0u64;
    while !p.is_done() {
        p.tick();
        n += 1;
        assert!(n <= bound, "player did not finish");
    }
}

/// Frames `payload` with a valid prefix and CRC, so the fuzzer reaches the header
/// and body parsers instead of stopping at the checksum.
fn sealed(magic: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let len = (10 + payload.len() + 4) as u32;
    let mut out = Vec::with_capacity(len as usize);
    out.extend_from_slice(magic);
    out.extend_from_slice(&1u16.to_le_bytes());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(payload);
    let crc = touch_protocol::container::crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

fuzz_target!(|data: &[u8]| {
    check(data);
    check(&sealed(b"TCHS", data));
    check(&sealed(b"TCHB", data));
});

fn check(data: &[u8]) {
    if let Ok(s) = Stimulus::decode(data) {
        assert_eq!(Stimulus::decode(s.as_bytes()).map(|t| t.as_bytes()), Ok(s.as_bytes()));
        play(&s);
    }
    if let Ok(bank) = Bank::decode(data) {
        for i in 0..bank.len() {
            let s = bank.slot(i).expect("a decoded bank's slots decode");
            play(&s);
        }
    }
}
