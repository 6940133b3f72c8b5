//! Byte-exact pins of link messages and frames (SPEC.md, "Link"): any change to
//! these bytes is a protocol change and needs a new `link::VERSION`.

use touch_protocol::link::{
    self, cobs, BankState, BankSummary, Busy, Command, Event, FrameError, Gesture, Info, Limit,
    LinkError, Message, PlayReply, Reply, Request, SlotInfo, Source, StatusReport, StopReply,
    StreamBeginReply, StreamParams, StreamStop,
};
use touch_protocol::Limits;

/// The postcard bytes of a message (no CRC, no COBS).
fn body<T: serde::Serialize>(m: &T) -> Vec<u8> {
    let mut buf = [0u8; link::MAX_MESSAGE];
    postcard::to_slice(m, &mut buf).unwrap().to_vec()
}

/// A request's bytes are pinned, and decode back to it.
fn pin_request(r: Request<'_>, expected: &[u8]) {
    assert_eq!(body(&r), expected, "{r:?}");
    assert_eq!(postcard::from_bytes::<Request>(expected).unwrap(), r);
}

/// A device message's bytes are pinned, and decode back to it.
fn pin_message(m: Message<'_>, expected: &[u8]) {
    assert_eq!(body(&m), expected, "{m:?}");
    assert_eq!(postcard::from_bytes::<Message>(expected).unwrap(), m);
}

fn req(seq: u16, command: Command<'_>) -> Request<'_> {
    Request { seq, command }
}

#[test]
fn requests_are_pinned() {
    pin_request(req(1, Command::Hello { version: 1 }), &[0x01, 0x00, 0x01]);
    pin_request(req(2, Command::Info), &[0x02, 0x01]);
    pin_request(req(3, Command::Slot { slot: 4 }), &[0x03, 0x02, 0x04]);
    pin_request(req(4, Command::Status), &[0x04, 0x03]);
    pin_request(
        req(
            5,
            Command::BankRead {
                offset: 0x0001_0000,
                len: 256,
            },
        ),
        // offset 65536 = varint 80 80 04, len 256 = 80 02
        &[0x05, 0x04, 0x80, 0x80, 0x04, 0x80, 0x02],
    );
    pin_request(
        req(
            6,
            Command::BankBegin {
                len: 1000,
                crc: 0xDEAD_BEEF,
            },
        ),
        // crc as a varint: 5 bytes for a 32-bit value with the top bits set
        &[0x06, 0x05, 0xE8, 0x07, 0xEF, 0xFD, 0xB6, 0xF5, 0x0D],
    );
    pin_request(
        req(
            2,
            Command::BankChunk {
                offset: 256,
                bytes: &[0xDE, 0xAD],
            },
        ),
        &[0x02, 0x06, 0x80, 0x02, 0x02, 0xDE, 0xAD],
    );
    pin_request(req(7, Command::BankCommit), &[0x07, 0x07]);
    pin_request(req(8, Command::BankAbort), &[0x08, 0x08]);
    // seq 300 = varint AC 02
    pin_request(
        req(300, Command::Play { slot: 3 }),
        &[0xAC, 0x02, 0x09, 0x03],
    );
    pin_request(req(9, Command::Stop), &[0x09, 0x0A]);
    pin_request(
        req(
            5,
            Command::StreamBegin(StreamParams {
                keyframe_period_ms: 40,
                ramp_ms: 20,
                full_scale_ma: 1000,
                limits: Limits::SLEEVE,
            }),
        ),
        &[
            0x05, 0x0B, 40, 20, 0xE8, 0x07, // period, ramp, full scale
            0xE8, 0x07, 50, 0xD8, 0x04, 0x80, 0x87, 0xA7, 0x0E, // limits
        ],
    );
    let mut k = [0u8; 16];
    link::put_stream_keyframes(&[[1, -1, 0, 0, 0, 0, 0, 0x1234]], &mut k);
    pin_request(
        req(
            10,
            Command::StreamData {
                index: 2,
                keyframes: &k,
            },
        ),
        &[
            0x0A, 0x0C, 0x02, 0x10, // seq, StreamData, index 2, 16 bytes
            0x01, 0x00, 0xFF, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x34, 0x12,
        ],
    );
    pin_request(req(11, Command::StreamEnd), &[0x0B, 0x0D]);
}

#[test]
fn replies_are_pinned() {
    let reply = |seq, reply| Message::Reply { seq, reply };
    pin_message(
        reply(
            1,
            Reply::Hello {
                version: 1,
                firmware: "0.1.0",
            },
        ),
        &[0x00, 0x01, 0x00, 0x01, 0x05, b'0', b'.', b'1', b'.', b'0'],
    );
    pin_message(
        reply(
            2,
            Reply::Info(Info {
                link_version: 1,
                firmware: "0.1.0",
                layout: "paper-2x4",
                layout_hash: 0x1234_5678,
                full_scale_ma: 1000,
                limits: Limits::SLEEVE,
                max_message: 288,
                max_chunk: 256,
                bank_capacity: 262_144,
                bank: BankState::Flashed(BankSummary {
                    len: 2000,
                    crc: 7,
                    slots: 6,
                }),
            }),
        ),
        &[
            0x00, 0x02, 0x01, // Reply, seq 2, Info
            0x01, // link version
            0x05, b'0', b'.', b'1', b'.', b'0', // firmware
            0x09, b'p', b'a', b'p', b'e', b'r', b'-', b'2', b'x', b'4', // layout
            0xF8, 0xAC, 0xD1, 0x91, 0x01, // layout hash 0x12345678
            0xE8, 0x07, // full scale
            0xE8, 0x07, 50, 0xD8, 0x04, 0x80, 0x87, 0xA7, 0x0E, // limits
            0xA0, 0x02, 0x80, 0x02, // max message 288, max chunk 256
            0x80, 0x80, 0x10, // bank capacity 262144
            0x00, 0xD0, 0x0F, 0x07, 0x06, // Flashed, len 2000, crc 7, 6 slots
        ],
    );
    pin_message(
        reply(
            3,
            Reply::Slot(SlotInfo {
                slot: 1,
                name: "love",
                duration_ms: 1500,
                playback_ms: 1540,
                playable: true,
            }),
        ),
        &[
            0x00, 0x03, 0x02, 0x01, 0x04, b'l', b'o', b'v', b'e', 0xDC, 0x0B, 0x84, 0x0C, 0x01,
        ],
    );
    pin_message(
        reply(
            4,
            Reply::Status(StatusReport {
                tick: 200,
                playing: Some(Source::Slot(2)),
                stopping: false,
                selected: 2,
                heat_permille: [0, 1, 2, 3, 4, 5, 6, 600],
                cooldown_ms: 300,
                faults: 1,
                last_fault: Some(link::FaultRecord {
                    tick: 100,
                    source: Source::Stream,
                    kind: Limit::Slew,
                    channel: 3,
                }),
                upload: None,
            }),
        ),
        &[
            0x00, 0x04, 0x03, // Reply, seq 4, Status
            0xC8, 0x01, // tick 200
            0x01, 0x00, 0x02, // Some(Slot(2))
            0x00, 0x02, // not stopping, selected 2
            0, 1, 2, 3, 4, 5, 6, 0xD8, 0x04, // heat per mille, no length prefix
            0xAC, 0x02, 0x01, // cooldown 300, 1 fault
            0x01, 0x64, 0x01, 0x01, 0x03, // Some: tick 100, Stream, Slew, channel 3
            0x00, // no upload
        ],
    );
    pin_message(
        reply(
            5,
            Reply::BankData {
                offset: 4,
                bytes: &[1, 2],
            },
        ),
        &[0x00, 0x05, 0x04, 0x04, 0x02, 0x01, 0x02],
    );
    pin_message(
        reply(6, Reply::BankBegin { len: 1000 }),
        &[0x00, 0x06, 0x05, 0xE8, 0x07],
    );
    pin_message(
        reply(7, Reply::BankChunk { next: 256 }),
        &[0x00, 0x07, 0x06, 0x80, 0x02],
    );
    pin_message(
        reply(8, Reply::BankCommit { crc: 1, slots: 2 }),
        &[0x00, 0x08, 0x07, 0x01, 0x02],
    );
    pin_message(reply(9, Reply::BankAbort), &[0x00, 0x09, 0x08]);
    // tick 123456 = varint C0 C4 07
    pin_message(
        reply(
            300,
            Reply::Play(PlayReply {
                slot: 3,
                tick: 123_456,
                now: true,
            }),
        ),
        &[0x00, 0xAC, 0x02, 0x09, 0x03, 0xC0, 0xC4, 0x07, 0x01],
    );
    pin_message(
        reply(
            10,
            Reply::Stop(StopReply {
                source: Some(Source::Stream),
                tick: 5,
            }),
        ),
        &[0x00, 0x0A, 0x0A, 0x01, 0x01, 0x05],
    );
    pin_message(
        reply(11, Reply::StreamBegin(StreamBeginReply { capacity: 32 })),
        &[0x00, 0x0B, 0x0B, 0x20],
    );
    pin_message(
        reply(12, Reply::StreamData { next: 16, room: 16 }),
        &[0x00, 0x0C, 0x0C, 0x10, 0x10],
    );
    pin_message(reply(13, Reply::StreamEnd), &[0x00, 0x0D, 0x0D]);
}

#[test]
fn refusals_events_and_unreadable_frames_are_pinned() {
    let refused = |seq, error| Message::Refused { seq, error };
    let cases: [(LinkError, &[u8]); 18] = [
        (LinkError::Malformed, &[0x00]),
        (LinkError::UnsupportedVersion { device: 2 }, &[0x01, 0x02]),
        (
            LinkError::NoSuchSlot { slot: 9, slots: 6 },
            &[0x02, 0x09, 0x06],
        ),
        (LinkError::BadSlot { slot: 1 }, &[0x03, 0x01]),
        (
            LinkError::TooHot {
                channel: 5,
                permille: 1000,
                cooldown_ms: 41_667,
            },
            &[0x04, 0x05, 0xE8, 0x07, 0xC3, 0xC5, 0x02],
        ),
        (LinkError::Busy(Busy::Playing), &[0x05, 0x00]),
        (LinkError::Busy(Busy::Uploading), &[0x05, 0x01]),
        (LinkError::Busy(Busy::Streaming), &[0x05, 0x02]),
        (LinkError::NoBank, &[0x06]),
        (LinkError::NoUpload, &[0x07]),
        (LinkError::OutOfOrder { expected: 512 }, &[0x08, 0x80, 0x04]),
        (LinkError::OutOfRange, &[0x09]),
        (
            LinkError::BadCrc {
                expected: 1,
                computed: 2,
            },
            &[0x0A, 0x01, 0x02],
        ),
        (LinkError::WrongLayout { slot: 3 }, &[0x0B, 0x03]),
        (LinkError::BadBank { blinks: 5 }, &[0x0C, 0x05]),
        (LinkError::Flash, &[0x0D]),
        (LinkError::NoStream, &[0x0E]),
        (LinkError::QueueFull, &[0x11]),
    ];
    for (error, bytes) in cases {
        let mut expected = vec![0x01, 0x04];
        expected.extend_from_slice(bytes);
        pin_message(refused(4, error), &expected);
    }
    pin_message(
        refused(4, LinkError::StreamGap { expected: 7 }),
        &[0x01, 0x04, 0x0F, 0x07],
    );
    pin_message(
        refused(4, LinkError::StreamFull { room: 3 }),
        &[0x01, 0x04, 0x10, 0x03],
    );

    let event = |tick, event| Message::Event { tick, event };
    let events: [(Event, &[u8]); 12] = [
        (Event::Button(Gesture::Toggle), &[0x00, 0x00]),
        (Event::Button(Gesture::Next), &[0x00, 0x01]),
        (Event::Button(Gesture::Slot(2)), &[0x00, 0x02, 0x02]),
        (Event::Started(Source::Slot(1)), &[0x01, 0x00, 0x01]),
        (Event::Stopping(Source::Stream), &[0x02, 0x01]),
        (Event::Finished(Source::Slot(0)), &[0x03, 0x00, 0x00]),
        (
            Event::LimitHit {
                source: Source::Slot(2),
                kind: Limit::Thermal,
                channel: 7,
            },
            &[0x04, 0x00, 0x02, 0x02, 0x07],
        ),
        (
            Event::TooHot {
                source: Source::Slot(0),
                channel: 1,
                permille: 600,
                cooldown_ms: 10,
            },
            &[0x05, 0x00, 0x00, 0x01, 0xD8, 0x04, 0x0A],
        ),
        (Event::Selected(4), &[0x06, 0x04]),
        (Event::BadSlot(4), &[0x07, 0x04]),
        (Event::StreamStopped(StreamStop::Deadline), &[0x08, 0x00]),
        (Event::StreamStopped(StreamStop::Ended), &[0x08, 0x02]),
    ];
    for (e, bytes) in events {
        // tick 1000 = varint E8 07
        let mut expected = vec![0x02, 0xE8, 0x07];
        expected.extend_from_slice(bytes);
        pin_message(event(1000, e), &expected);
    }
    pin_message(Message::Unreadable(FrameError::BadCrc), &[0x03, 0x03]);
    pin_message(Message::Unreadable(FrameError::TooLong), &[0x03, 0x00]);
    pin_message(Message::Unreadable(FrameError::Overrun), &[0x03, 0x05]);
}

/// Whole frames on the wire: postcard, CRC-32 LE, COBS, 00 (CRCs from Python's
/// `zlib.crc32`).
#[test]
fn frames_are_pinned() {
    let mut wire = [0u8; link::MAX_ENCODED];
    let n = link::encode(&req(300, Command::Play { slot: 3 }), &mut wire).unwrap();
    assert_eq!(
        &wire[..n],
        &[0x09, 0xAC, 0x02, 0x09, 0x03, 0x3C, 0x47, 0xB6, 0x6D, 0x00]
    );
    let play = Message::Reply {
        seq: 300,
        reply: Reply::Play(PlayReply {
            slot: 3,
            tick: 123_456,
            now: true,
        }),
    };
    let n = link::encode(&play, &mut wire).unwrap();
    // The message starts with a zero (Reply): COBS code 01 stands for it.
    assert_eq!(
        &wire[..n],
        &[
            0x01, 0x0D, 0xAC, 0x02, 0x09, 0x03, 0xC0, 0xC4, 0x07, 0x01, 0x97, 0xAA, 0x76, 0x34,
            0x00
        ]
    );
    let chunk = req(
        2,
        Command::BankChunk {
            offset: 256,
            bytes: &[0xDE, 0xAD],
        },
    );
    let n = link::encode(&chunk, &mut wire).unwrap();
    assert_eq!(
        &wire[..n],
        &[0x0C, 0x02, 0x06, 0x80, 0x02, 0x02, 0xDE, 0xAD, 0xF9, 0xB6, 0x1D, 0x73, 0x00]
    );
    // And back through the streaming decoder, after garbage.
    let mut d = cobs::Decoder::<{ link::MAX_ENCODED }>::new();
    let mut got = Vec::new();
    for &b in [0x42, 0x13, 0x00].iter().chain(&wire[..n]) {
        match d.feed(b) {
            cobs::Feed::Frame(f) => got.push(Ok(link::decode::<Request>(f).map(|r| r.seq))),
            cobs::Feed::Dropped(e) => got.push(Err(e)),
            cobs::Feed::Pending => {}
        }
    }
    assert_eq!(got, vec![Err(cobs::CobsError::Malformed), Ok(Ok(2))]);
}

/// Every truncation of a good frame is refused, never misread.
#[test]
fn truncated_frames_are_refused() {
    let mut wire = [0u8; link::MAX_ENCODED];
    let n = link::encode(&req(2, Command::BankBegin { len: 9, crc: 1 }), &mut wire).unwrap();
    for cut in 0..n - 1 {
        let mut raw = [0u8; link::MAX_FRAME];
        match cobs::decode(&wire[..cut], &mut raw) {
            Err(_) => {}
            Ok(m) => assert!(
                link::decode::<Request>(&raw[..m]).is_err(),
                "cut at {cut} decoded"
            ),
        }
    }
}
