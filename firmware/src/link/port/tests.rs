//! [`TickReply`] mirrors the link's [`Reply`]: the variants the tick gives, field
//! for field.

use touch_protocol::link::{self, cobs, Message, Reply, Source};

use super::TickReply;

/// The tick's reply a wire reply mirrors, if the tick gives it: the inverse of
/// `From<TickReply> for Reply`. Exhaustive over `Reply`'s variants and, without
/// `..`, over each mirrored variant's fields: a variant or a field added to
/// `Reply` fails to build here until the mirror (or the list of the server's
/// replies) follows it, as one added to `TickReply` fails in `From`.
fn mirror(r: Reply<'_>) -> Option<TickReply> {
    match r {
        Reply::Play { slot, tick, now } => Some(TickReply::Play { slot, tick, now }),
        Reply::Stop { source, tick } => Some(TickReply::Stop { source, tick }),
        Reply::StreamBegin { capacity } => Some(TickReply::StreamBegin { capacity }),
        Reply::StreamEnd => Some(TickReply::StreamEnd),
        // The link server's own replies: the tick never gives these.
        Reply::Hello { .. }
        | Reply::Info(_)
        | Reply::Slot(_)
        | Reply::Status(_)
        | Reply::BankData { .. }
        | Reply::BankBegin { .. }
        | Reply::BankChunk { .. }
        | Reply::BankCommit { .. }
        | Reply::BankAbort
        | Reply::StreamData { .. } => None,
    }
}

/// One of each variant and each `Source` (fields of the same type hold different
/// values, so that a swapped pair does not survive the round trip).
fn every_reply() -> Vec<TickReply> {
    vec![
        TickReply::Play {
            slot: 3,
            tick: 0x1234_5678,
            now: true,
        },
        TickReply::Play {
            slot: 250,
            tick: 7,
            now: false,
        },
        TickReply::Stop {
            source: Some(Source::Slot(4)),
            tick: 99,
        },
        TickReply::Stop {
            source: Some(Source::Stream),
            tick: 0,
        },
        TickReply::Stop {
            source: None,
            tick: u32::MAX,
        },
        TickReply::StreamBegin { capacity: 32 },
        TickReply::StreamEnd,
    ]
}

#[test]
fn every_variant_is_in_the_list() {
    // Exhaustive: a variant added to `TickReply` fails to build here, and its arm
    // needs a place of its own (a constant index past the array is a build error
    // too), which stays false until `every_reply` has one.
    let mut seen = [false; 4];
    for r in every_reply() {
        match r {
            TickReply::Play { .. } => seen[0] = true,
            TickReply::Stop { .. } => seen[1] = true,
            TickReply::StreamBegin { .. } => seen[2] = true,
            TickReply::StreamEnd => seen[3] = true,
        }
    }
    assert_eq!(seen, [true; 4]);
}

#[test]
fn every_variant_round_trips() {
    for r in every_reply() {
        assert_eq!(mirror(Reply::from(r)), Some(r), "{r:?}");
    }
}

#[test]
fn every_variant_survives_the_wire() {
    for r in every_reply() {
        let m = Message::Reply {
            seq: 0x5A5A,
            reply: Reply::from(r),
        };
        let mut stuffed = [0u8; link::MAX_ENCODED];
        let n = link::encode(&m, &mut stuffed).unwrap();
        let mut frame = [0u8; link::MAX_FRAME];
        // The frame without its closing 0x00.
        let len = cobs::decode(&stuffed[..n - 1], &mut frame).unwrap();
        match link::decode::<Message>(&frame[..len]).unwrap() {
            Message::Reply { seq, reply } => {
                assert_eq!(seq, 0x5A5A);
                assert_eq!(mirror(reply), Some(r), "{r:?}");
            }
            other => panic!("{r:?} came back as {other:?}"),
        }
    }
}

#[test]
fn the_servers_replies_are_not_the_ticks() {
    assert_eq!(mirror(Reply::BankAbort), None);
    assert_eq!(mirror(Reply::StreamData { next: 3, room: 4 }), None);
}
