//! [`DeviceInfo`] is the wire's [`link::Info`] with its text owned: what a host keeps
//! of a real frame.

use touch_protocol::link::{self, cobs, BankState, BankSummary, Message, Reply};
use touch_protocol::Limits;

use super::DeviceInfo;

/// An `Info` for each bank state; fields of the same type hold different values,
/// so that a swapped pair does not survive the round trip.
fn every_info() -> Vec<link::Info<&'static str>> {
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
fn owned_text_keeps_each_string_in_its_field() {
    for info in every_info() {
        let owned: DeviceInfo = info.map_text(str::to_owned);
        assert_eq!(
            (owned.firmware.as_str(), owned.layout.as_str()),
            ("0.1.0", "sleeve-2x4")
        );
        assert_eq!(owned.map_text(|_| ()), info.map_text(|_| ()));
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
        // What the host keeps of a real frame is the `Info` sent.
        let kept: DeviceInfo = back.map_text(str::to_owned);
        assert_eq!(kept, info.map_text(str::to_owned));
    }
}
