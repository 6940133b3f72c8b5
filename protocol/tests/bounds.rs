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
        residual_k: 2,
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

/// A body written bit by bit, most significant first (SPEC.md), as the test's own
/// writer.
#[derive(Default)]
struct Bits(Vec<bool>);

impl Bits {
    fn push(mut self, value: u64, n: u32) -> Self {
        self.0.extend((0..n).rev().map(|i| (value >> i) & 1 == 1));
        self
    }

    /// Order-0 Exp-Golomb: zeros, then `value + 1` from its leading one.
    fn exp_golomb(self, value: u32) -> Self {
        let x = u64::from(value) + 1;
        let len = 64 - x.leading_zeros();
        self.push(0, len - 1).push(x, len)
    }

    fn bytes(self) -> Vec<u8> {
        self.0
            .chunks(8)
            .map(|c| (0..8).fold(0u8, |b, i| b << 1 | u8::from(c.get(i) == Some(&true))))
            .collect()
    }
}

/// A body that is one record skipping all `n` keyframes.
fn run(n: u32) -> Vec<u8> {
    Bits::default().exp_golomb(n).bytes()
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
        // Keyframe 0 after a skip of 0: mask `1000_0000` (channel 0), residual +1
        // (zigzag 2, code value 1, Rice k = 2: `0 01`); then a skip of the rest.
        Bits::default()
            .exp_golomb(0)
            .push(0x80, 8)
            .push(0b001, 3)
            .exp_golomb(n)
            .bytes()
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
