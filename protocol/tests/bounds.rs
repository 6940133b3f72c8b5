//! Bounded work for every input: files crafted to declare huge signals in a few bytes
//! decode (or are refused) in time proportional to their bytes, and play with
//! saturating time arithmetic.

use touch_protocol::stimulus::{self, Header, MAX_DURATION_MS, MAX_KEYFRAMES};
use touch_protocol::{container, Bank, DeviceConfig, Error, Limits, Player, Status, Stimulus};

fn header(period: u16, count: u32, duration: u32) -> Header<'static> {
    Header {
        channels: 8,
        output_rate_hz: 1000,
        keyframe_period_ms: period,
        keyframe_count: count,
        duration_ms: duration,
        ramp_ms: 10,
        full_scale_ma: 1000,
        quant_shift: 0,
        layout_hash: 1,
        layout: "t",
        limits: Limits::SLEEVE,
        name: "huge",
    }
}

/// A sealed stimulus file: `header` as given (not recomputed), then `body`.
fn craft(header: &Header<'_>, body: &[u8]) -> Vec<u8> {
    let mut head = [0u8; stimulus::HEADER_MAX_LEN];
    let mut payload = postcard::to_slice(header, &mut head).unwrap().to_vec();
    payload.extend_from_slice(body);
    container::seal(stimulus::MAGIC, stimulus::VERSION, &payload).unwrap()
}

/// A run record of `n` keyframes.
fn run(n: u32) -> Vec<u8> {
    let mut buf = [0u8; 5];
    let mut body = vec![0u8];
    body.extend_from_slice(postcard::to_slice(&n, &mut buf).unwrap());
    body
}

/// The 60-byte stimulus of 2^32 - 1 keyframes that took 88 s to check: refused by
/// the documented maximum, before any keyframe is looked at.
#[test]
fn keyframe_counts_past_the_maximum_are_refused() {
    let count = u32::MAX;
    let file = craft(&header(1, count, count - 1), &run(count));
    assert!(file.len() < 70, "{} bytes", file.len());
    assert_eq!(
        Stimulus::decode(&file).unwrap_err(),
        Error::InvalidField("keyframe_count")
    );
    // duration_ms = u32::MAX (which overflowed `t + 1` in the player): refused.
    let n = 858_993_459; // (n) * 5 = u32::MAX
    let file = craft(&header(5, n + 1, u32::MAX), &run(n + 1));
    assert!(Stimulus::decode(&file).is_err());
    let file = craft(
        &header(1000, MAX_DURATION_MS / 1000 + 2, MAX_DURATION_MS + 1000),
        &run(MAX_DURATION_MS / 1000 + 2),
    );
    assert_eq!(
        Stimulus::decode(&file).unwrap_err(),
        Error::InvalidField("duration_ms")
    );
}

/// A day at 1 ms, the largest stimulus the format allows, in a few bytes: a run is
/// checked in one step, and the line it follows is range-checked at its far end.
#[test]
fn a_maximal_run_decodes_in_one_step_and_its_line_is_checked() {
    let file = craft(
        &header(1, MAX_KEYFRAMES, MAX_DURATION_MS),
        &run(MAX_KEYFRAMES),
    );
    let s = Stimulus::decode(&file).unwrap();
    assert_eq!(s.duration_ms(), MAX_DURATION_MS);
    // A line rising 1 per keyframe (residual +1 on channel 0 then a run) leaves the
    // i16 range after 32,767 keyframes: a long run of it is refused, a short one not.
    let body = |n: u32| {
        let mut b = vec![0x01, 0x02]; // keyframe 0: ch0 = 0 + 1 (zigzag 2)
        b.extend_from_slice(&run(n));
        b
    };
    let ok = craft(&header(1, 32_767, 32_766), &body(32_766));
    let s = Stimulus::decode(&ok).unwrap();
    assert_eq!(s.keyframes().last().unwrap()[0], 32_767);
    let over = craft(&header(1, 1_000_001, 1_000_000), &body(1_000_000));
    assert_eq!(
        Stimulus::decode(&over).unwrap_err(),
        Error::KeyframeOutOfRange
    );
}

/// The player's clocks saturate: a day-long stimulus plays its first and last
/// ticks without overflow, and a stop from deep inside it ramps to rest.
#[test]
fn the_longest_stimulus_plays_and_stops() {
    let file = craft(
        &header(1, MAX_KEYFRAMES, MAX_DURATION_MS),
        &run(MAX_KEYFRAMES),
    );
    let s = Stimulus::decode(&file).unwrap();
    let mut p = Player::new(&s, &DeviceConfig::default());
    assert_eq!(p.tick().status, Status::Playing);
    p.stop();
    let rest: Vec<_> = p.by_ref().collect();
    assert_eq!(rest.last().map(|t| t.status), Some(Status::Finished));
    assert!(rest.len() <= 11);
}

/// Bank slots of the largest stimuli read back as they were packed (`slot()` reads
/// the header again and trusts the keyframes `Bank::decode` validated).
#[test]
fn bank_slots_of_maximal_stimuli_read_back() {
    let one = craft(
        &header(1, MAX_KEYFRAMES, MAX_DURATION_MS),
        &run(MAX_KEYFRAMES),
    );
    let image = touch_protocol::bank::encode(&[&one, &one]).unwrap();
    let bank = Bank::decode(&image).unwrap();
    assert_eq!(bank.slot(1).unwrap().duration_ms(), MAX_DURATION_MS);
    assert_eq!(bank.stimuli().count(), 2);
}
