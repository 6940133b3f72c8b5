//! [`DeviceInfo`] mirrors the wire's [`link::Info`], field for field.

use touch_protocol::link::{self, cobs, BankState, BankSummary, Message, Reply};
use touch_protocol::Limits;

use super::DeviceInfo;

/// The wire's `Info` a `DeviceInfo` stands for: the inverse of `From`. Every field
/// named, without `..`: a field added to `DeviceInfo` fails to build here, as one
/// added to `link::Info` fails in `From`.
fn wire(d: &DeviceInfo) -> link::Info<'_> {
    let DeviceInfo {
        link_version,
        firmware,
        layout,
        layout_hash,
        full_scale_ma,
        limits,
        max_message,
        max_chunk,
        bank_capacity,
        bank,
    } = d;
    link::Info {
        link_version: *link_version,
        firmware,
        layout,
        layout_hash: *layout_hash,
        full_scale_ma: *full_scale_ma,
        limits: *limits,
        max_message: *max_message,
        max_chunk: *max_chunk,
        bank_capacity: *bank_capacity,
        bank: *bank,
    }
}

/// An `Info` for each bank state; fields of the same type hold different values,
/// so that a swapped pair does not survive the round trip.
fn every_info() -> Vec<link::Info<'static>> {
    let summary = |len, crc, slots| BankSummary { len, crc, slots };
    [
        BankState::Flashed(summary(4096, 0xDEAD_BEEF, 6)),
        BankState::Builtin(summary(812, 0x0BAD_F00D, 2)),
        BankState::Refused { blinks: 4 },
    ]
    .into_iter()
    .map(|bank| link::Info {
        link_version: 3,
        firmware: "0.1.0",
        layout: "sleeve-2x4",
        layout_hash: 0x1234_5678,
        full_scale_ma: 1000,
        limits: Limits {
            peak_ma: 900,
            slew_ma_per_ms: 50,
            continuous_ma: 300,
            i2t_budget_ma2s: 400_000,
        },
        max_message: 700,
        max_chunk: 512,
        bank_capacity: 262_144,
        bank,
    })
    .collect()
}

#[test]
fn device_info_round_trips_every_bank_state() {
    for info in every_info() {
        let owned = DeviceInfo::from(info);
        assert_eq!(wire(&owned), info);
        assert_eq!(DeviceInfo::from(wire(&owned)), owned);
    }
}

#[test]
fn device_info_round_trips_through_the_wire() {
    for info in every_info() {
        let m = Message::Reply {
            seq: 9,
            reply: Reply::Info(info),
        };
        let mut stuffed = [0u8; link::MAX_ENCODED];
        let n = link::encode(&m, &mut stuffed).unwrap();
        let mut frame = [0u8; link::MAX_FRAME];
        // The frame without its closing 0x00.
        let len = cobs::decode(&stuffed[..n - 1], &mut frame).unwrap();
        let Ok(Message::Reply {
            reply: Reply::Info(back),
            ..
        }) = link::decode::<Message>(&frame[..len])
        else {
            panic!("{info:?} did not come back as Info");
        };
        // What the host reads from a real frame stands for the `Info` sent.
        assert_eq!(wire(&DeviceInfo::from(back)), info);
    }
}
