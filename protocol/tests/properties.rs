//! Invariants over random inputs: decoding never panics, encoding round-trips, and
//! the player never leaves its limits.

use proptest::prelude::*;
use touch_protocol::player::{code_to_amps, LimitKind};
use touch_protocol::{
    bank, stimulus, Bank, DeviceConfig, Limits, Player, Status, Stimulus, CHANNELS, IDLE_CODE,
};

fn builder(period: u16, ramp: u16, shift: u8, limits: Limits) -> stimulus::Builder<'static> {
    stimulus::Builder::new("prop", period)
        .ramp_ms(ramp)
        .quant_shift(shift)
        .layout("t", 1)
        .limits(limits)
}

fn keyframes(max_len: usize) -> impl Strategy<Value = Vec<[i16; CHANNELS]>> {
    prop::collection::vec(prop::array::uniform8(any::<i16>()), 1..max_len)
}

fn limits() -> impl Strategy<Value = Limits> {
    (1u16..3000, 1u16..200, 0u16..1500, 0u32..50_000_000).prop_map(|(p, s, c, b)| Limits {
        peak_ma: p,
        slew_ma_per_ms: s,
        continuous_ma: c,
        i2t_budget_ma2s: b,
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn any_bytes_decode_without_panic(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        let _ = Stimulus::decode(&bytes);
        let _ = Bank::decode(&bytes);
    }

    #[test]
    fn damaged_files_decode_without_panic(
        kf in keyframes(20), at in any::<prop::sample::Index>(), byte in any::<u8>(),
        fix_crc in any::<bool>(),
    ) {
        let mut bytes = builder(20, 5, 3, Limits::SLEEVE).encode(&kf).unwrap();
        let i = at.index(bytes.len());
        bytes[i] = byte;
        if fix_crc {
            // Re-seal so decoding gets past the CRC and into the header and body.
            let n = bytes.len();
            let crc = touch_protocol::container::crc32(&bytes[..n - 4]);
            bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
        }
        if let Ok(s) = Stimulus::decode(&bytes) {
            // Whatever decodes also plays to the end.
            let mut p = Player::new(&s, &DeviceConfig::default());
            let ticks = p.by_ref().take(2_000_000).count();
            prop_assert!(p.is_done(), "{} ticks", ticks);
        }
        let image = bank::encode(&[&builder(20, 5, 0, Limits::SLEEVE).encode(&kf).unwrap()]).unwrap();
        let mut image2 = image.clone();
        let j = at.index(image2.len());
        image2[j] = byte;
        let _ = Bank::decode(&image2);
    }

    #[test]
    fn encode_decode_round_trips(kf in keyframes(50), shift in 0u8..=15, period in 1u16..=1000) {
        let bytes = builder(period, 10, shift, Limits::SLEEVE).encode(&kf).unwrap();
        let s = Stimulus::decode(&bytes).unwrap();
        let back: Vec<_> = s.keyframes().collect();
        prop_assert_eq!(back.len(), kf.len());
        for (got, want) in back.iter().zip(&kf) {
            for c in 0..CHANNELS {
                let q = stimulus::quantise(want[c], shift) << shift;
                prop_assert_eq!(i32::from(got[c]), q);
                // Quantisation moves a value by at most half a step (or the clamp at +full scale).
                prop_assert!((i32::from(got[c]) - i32::from(want[c])).abs() <= (1 << shift));
            }
        }
        prop_assert_eq!(s.duration_ms(), (kf.len() as u32 - 1) * u32::from(period));
        // Re-encoding the decoded values gives the same bytes: one encoding per signal.
        prop_assert_eq!(builder(period, 10, shift, Limits::SLEEVE).encode(&back).unwrap(), bytes);
    }

    #[test]
    fn player_stays_within_limits(
        kf in keyframes(12), period in 1u16..60, ramp in 1u16..300,
        stim_limits in limits(), dev_limits in limits(), dev_fs in 100u16..3000,
        stop_at in prop::option::of(0u32..800),
    ) {
        let bytes = builder(period, ramp, 0, stim_limits).encode(&kf).unwrap();
        let s = Stimulus::decode(&bytes).unwrap();
        let device = DeviceConfig { full_scale_ma: dev_fs, limits: dev_limits };
        let eff = stim_limits.min(dev_limits);
        let (peak, slew) = (i32::from(eff.peak_ma) * 1000, i32::from(eff.slew_ma_per_ms) * 1000);
        let mut p = Player::new(&s, &device);
        let mut prev = [0i32; CHANNELS];
        let mut faults = 0;
        let bound = s.header().playback_ms() as u64 + 1 + 2 * u64::from(eff.peak_ma) / u64::from(eff.slew_ma_per_ms.max(1)) + 2;
        let mut n = 0u64;
        loop {
            if Some(n as u32) == stop_at { p.stop(); }
            let t = p.tick();
            n += 1;
            let out = p.output_ua();
            for c in 0..CHANNELS {
                prop_assert!(out[c].abs() <= peak, "peak: {} > {}", out[c], peak);
                prop_assert!((out[c] - prev[c]).abs() <= slew, "slew at {}", n);
                // The code is the current, rounded, on the device's scale.
                let amps = code_to_amps(t.codes[c], dev_fs);
                let want = (f64::from(out[c]) / 1e6).clamp(-f64::from(dev_fs) / 1000.0, f64::from(dev_fs) / 1000.0 * 2047.0 / 2048.0);
                prop_assert!((amps - want).abs() <= f64::from(dev_fs) / 1000.0 / 2048.0 * 0.501, "code {} amps {} want {} fs {}", t.codes[c], amps, want, dev_fs);
            }
            prev = out;
            if let Status::Fault(_) = t.status { faults += 1; }
            if t.status == Status::Finished {
                prop_assert_eq!(t.codes, [IDLE_CODE; CHANNELS]);
                break;
            }
            prop_assert!(n <= bound, "still running after {} ticks (bound {})", n, bound);
        }
        prop_assert!(faults <= 1, "a fault is reported once");
        prop_assert_eq!(p.tick().codes, [IDLE_CODE; CHANNELS]);
    }
}

/// A smooth signal within the limits plays without a fault and hits every keyframe
/// value exactly at its tick.
#[test]
fn keyframes_are_hit_exactly() {
    let kf: Vec<[i16; 8]> = (0..11)
        .map(|k| {
            let v = (k * 1000) as i16;
            [v, -v, 0, v / 2, 0, 0, 0, 3277]
        })
        .collect();
    let bytes = builder(40, 10, 0, Limits::SLEEVE).encode(&kf).unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut p = Player::new(&s, &DeviceConfig::default());
    let mut outs = Vec::new();
    while !p.is_done() {
        let t = p.tick();
        assert!(!matches!(t.status, Status::Fault(_)), "{:?}", t.status);
        outs.push(p.output_ua());
    }
    for (k, frame) in kf.iter().enumerate().skip(1) {
        let tick = k * 40;
        for c in 0..CHANNELS {
            let want = (i64::from(frame[c]) * 1_000_000) >> 15;
            assert_eq!(i64::from(outs[tick][c]), want, "keyframe {k} channel {c}");
        }
    }
    // Signal ticks 0..=400, then 10 ramp ticks (31 mA each, within the slew) ending at 0 A.
    assert_eq!(outs.len(), 401 + 10);
    assert_eq!(*outs.last().unwrap(), [0; 8]);
    // Linear in between: tick 20 is halfway from keyframe 0 to 1 on channel 0.
    assert_eq!(outs[20][0], ((500i64 * 1_000_000) >> 15) as i32);
}

#[test]
fn limit_hits_fault_and_ramp_to_zero() {
    // A step to +0.9 A against a 10 mA/ms slew limit.
    let kf = vec![[0; 8], [29491, 0, 0, 0, 0, 0, 0, 0]];
    let strict = Limits {
        slew_ma_per_ms: 10,
        ..Limits::SLEEVE
    };
    let bytes = builder(2, 1, 0, strict).encode(&kf).unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut p = Player::new(&s, &DeviceConfig::default());
    let statuses: Vec<_> = p.by_ref().map(|t| t.status).collect();
    assert!(matches!(statuses[1], Status::Fault(f) if f.kind == LimitKind::Slew && f.channel == 0));
    assert_eq!(*statuses.last().unwrap(), Status::Finished);
    assert_eq!(p.fault().map(|f| f.kind), Some(LimitKind::Slew));

    // Holding 1 A against a 0.5 A continuous rating with a 1 A^2 s budget fills it at
    // (1 - 0.25) A^2 per second, in 1.333 s. The player stops early enough for one
    // more tick and the ramp down to fit (a 1 ms ramp: 4 ticks of reserve at 1 A)
    // and accounts the current rounded up to the code's (1.001 A): 752,001 mA^2 per
    // tick passes 1e9 - 4 * 1001^2 mA^2 ms after 1,325 ticks, so tick index 1325
    // is the fault.
    let kf = vec![[32767; 8]; 3];
    let hot = Limits {
        continuous_ma: 500,
        i2t_budget_ma2s: 1_000_000,
        slew_ma_per_ms: 1001,
        ..Limits::SLEEVE
    };
    let bytes = builder(1000, 1, 0, hot).encode(&kf).unwrap();
    let s = Stimulus::decode(&bytes).unwrap();
    let mut p = Player::new(
        &s,
        &DeviceConfig {
            full_scale_ma: 1000,
            limits: hot,
        },
    );
    let at = p
        .by_ref()
        .position(|t| matches!(t.status, Status::Fault(_)))
        .unwrap();
    assert_eq!(at, 1325, "thermal trip");
    assert_eq!(p.fault().map(|f| f.kind), Some(LimitKind::Thermal));
}

proptest! {
    /// Signals that mostly hold still or ramp: long skips, round-tripped exactly, and
    /// each skip costs a few bits however long it is.
    #[test]
    fn sparse_changes_round_trip(changes in prop::collection::vec((0usize..400, 0usize..8, any::<i16>()), 0..6)) {
        let mut kf = vec![[0i16; CHANNELS]; 400];
        for &(at, ch, v) in &changes {
            for frame in kf.iter_mut().skip(at) {
                frame[ch] = v;
            }
        }
        let bytes = builder(20, 10, 0, Limits::SLEEVE).encode(&kf).unwrap();
        let s = Stimulus::decode(&bytes).unwrap();
        prop_assert_eq!(s.keyframes().collect::<Vec<_>>(), kf);
        // Each change costs at most two records (the step and the stop of its line).
        prop_assert!(bytes.len() <= 10 + 35 + 4 + 2 + changes.len() * 2 * (1 + 3 + 2 + 3) + 3);
    }
}

#[test]
fn skips_must_be_canonical() {
    let kf = vec![[0i16; CHANNELS]; 5];
    let bytes = builder(20, 10, 0, Limits::SLEEVE).encode(&kf).unwrap();
    let n = bytes.len();
    // The body is one record skipping all 5: Exp-Golomb `00110`, padded: `0011_0000`.
    assert_eq!(bytes[n - 5], 0x30);
    let reseal = |body: &[u8]| {
        let mut b = bytes[..n - 5].to_vec();
        b.extend_from_slice(body);
        let len = (b.len() + 4) as u32;
        b[6..10].copy_from_slice(&len.to_le_bytes());
        let crc = touch_protocol::container::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    };
    assert!(Stimulus::decode(&reseal(&[0x30])).is_ok());
    // Skip 2, then a "change" of no channel (`011 0000_0000`) and a skip of 2: a
    // second encoding of the same signal, refused.
    assert_eq!(
        Stimulus::decode(&reseal(&[0b0110_0000, 0b0000_1100])).unwrap_err(),
        touch_protocol::Error::KeyframeOutOfRange
    );
    // A skip past the keyframes left (6: `00111`), a change cut short, a pad bit set,
    // a byte after the body.
    for body in [&[0x38][..], &[0x80], &[0x31], &[0x30, 0x00]] {
        assert!(Stimulus::decode(&reseal(body)).is_err(), "{body:02x?}");
    }
}
