//! Any bytes, as a stimulus and as a bank: decoding returns `Ok` or an error and
//! never panics; whatever decodes also plays to the end within its stated length.
#![no_main]

use libfuzzer_sys::fuzz_target;
use touch_protocol::{Bank, DeviceConfig, Player, Stimulus};

/// Ticks played before a stop: stimuli may last a day, an execution may not.
const PLAY_TICKS: u64 = 100_000;

fn play(s: &Stimulus<'_>) {
    let mut p = Player::new(s, &DeviceConfig::default());
    // Signal (or a stop after PLAY_TICKS), ramp, and a slew-limited tail of at most
    // peak / slew ticks.
    let bound = u64::from(s.header().playback_ms()).min(PLAY_TICKS) + 1 + 2_000 + u64::from(s.header().ramp_ms);
    let mut n = 0u64;
    while !p.is_done() {
        if n == PLAY_TICKS {
            p.stop();
        }
        p.tick();
        n += 1;
        assert!(n <= bound, "player did not finish");
    }
}


/// Frames `payload` with a valid prefix, the format's current version and CRC, so the
/// fuzzer reaches the header and body parsers instead of stopping at the checksum or
/// the version check.
fn sealed(magic: [u8; 4], version: u16, payload: &[u8]) -> Vec<u8> {
    touch_protocol::container::seal(magic, version, payload).expect("fuzz inputs are small")
}

fuzz_target!(|data: &[u8]| {
    use touch_protocol::{bank, stimulus};
    check(data);
    check(&sealed(stimulus::MAGIC, stimulus::VERSION, data));
    check(&sealed(bank::MAGIC, bank::VERSION, data));
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
