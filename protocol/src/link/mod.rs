//! The link between the sleeve and a computer (USB CDC-ACM or a USART): the same
//! frames on both.
//!
//! A frame on the wire is a postcard-encoded message followed by its CRC-32 (u32
//! LE, of the message bytes), COBS-stuffed ([`cobs`]) and ended by one `0x00`:
//!
//! ```text
//! COBS( postcard(message) ++ crc32(postcard(message)) ) 00
//! ```
//!
//! The host sends [`Request`]s (a sequence number and a [`Command`]); the device
//! answers each with a [`Message::Reply`] or a [`Message::Refused`] carrying the same
//! sequence number, and pushes [`Message::Event`]s, each with its 1 kHz tick, as
//! they happen. A frame that does not decode is answered with
//! [`Message::Unreadable`]. `SPEC.md` ("Link") describes every byte.
//!
//! ```
//! use touch_protocol::link::{self, Command, Request};
//! let mut wire = [0u8; link::MAX_ENCODED];
//! let n = link::encode(&Request { seq: 7, command: Command::Info }, &mut wire)?;
//! assert_eq!(&wire[..n], &[0x07, 0x07, 0x01, 0xae, 0xb4, 0x9f, 0x79, 0x00]);
//!
//! let mut decoder = link::cobs::Decoder::<{ link::MAX_ENCODED }>::new();
//! let mut frames = 0;
//! for &b in &wire[..n] {
//!     if let link::cobs::Feed::Frame(frame) = decoder.feed(b) {
//!         let request: Request = link::decode(frame)?;
//!         assert_eq!(request, Request { seq: 7, command: Command::Info });
//!         frames += 1;
//!     }
//! }
//! assert_eq!(frames, 1);
//! # Ok::<(), link::FrameError>(())
//! ```

pub mod cobs;
mod message;
mod playback;
mod ser;

pub use message::{
    BankState, BankSummary, Busy, Command, Event, FaultRecord, Gesture, Info, Limit, LinkError,
    Message, Reply, Request, SlotInfo, Source, StatusReport, StreamParams, StreamStop,
};
pub use playback::{PlayReply, StopReply, StreamBeginReply, TickReply};

use serde::{Deserialize, Serialize};

/// The link protocol's version; [`Command::Hello`] and [`Info`] carry it.
pub const VERSION: u16 = 1;

/// Largest payload of a `BankChunk`, `BankRead` or `StreamData`, bytes.
pub const MAX_CHUNK: usize = 256;

/// Largest postcard message either side sends or takes, bytes: a chunk of
/// [`MAX_CHUNK`] bytes with its fields fits, with room to spare.
pub const MAX_MESSAGE: usize = MAX_CHUNK + 32;

/// Bytes of the CRC after the message.
pub const CRC_LEN: usize = 4;

/// Largest frame before stuffing: a message and its CRC.
pub const MAX_FRAME: usize = MAX_MESSAGE + CRC_LEN;

/// Largest frame on the wire: stuffed, with its terminating zero. A receiver
/// buffers this much.
pub const MAX_ENCODED: usize = cobs::max_encoded_len(MAX_FRAME) + 1;

/// Bytes of one stream keyframe: eight i16 LE.
pub const KEYFRAME_LEN: usize = 16;

/// Most keyframes in one `StreamData`.
pub const MAX_STREAM_KEYFRAMES: usize = MAX_CHUNK / KEYFRAME_LEN;

/// A playing stream whose buffer ran dry and that got no data for this long ramps
/// to 0 A (the host is gone).
pub const STREAM_DEADLINE_MS: u32 = 50;

/// A stream begun but not yet playing (fewer than two keyframes in) that gets no
/// data for this long is forgotten. Nothing plays meanwhile, so it may wait out a
/// host's stall longer than the playing stream's deadline.
pub const STREAM_START_MS: u32 = 1000;

/// Why a frame could not be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Longer than [`MAX_ENCODED`] (or the caller's buffer).
    TooLong,
    /// Not valid COBS.
    Cobs,
    /// Shorter than a CRC.
    Short,
    /// The CRC does not match: damaged on the way.
    BadCrc,
    /// The CRC matches but the message does not decode (another version, or not a
    /// message of this kind, or bytes after the message).
    Malformed,
    /// The frame was dropped unread: the device's receive buffer was full (a host
    /// that sent faster than the device answers, on a wire that cannot wait).
    Overrun,
}

impl From<cobs::CobsError> for FrameError {
    fn from(e: cobs::CobsError) -> Self {
        match e {
            cobs::CobsError::Malformed => FrameError::Cobs,
            cobs::CobsError::Overflow => FrameError::TooLong,
        }
    }
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "frame too long",
            FrameError::Cobs => "frame is not valid COBS",
            FrameError::Short => "frame shorter than its CRC",
            FrameError::BadCrc => "frame CRC mismatch",
            FrameError::Malformed => "frame does not decode as a message",
            FrameError::Overrun => "frame dropped: the receive buffer was full",
        })
    }
}

impl core::error::Error for FrameError {}

/// Encodes `message` as one wire frame (postcard, CRC-32, COBS, `0x00`) into `out`;
/// returns its length. `out` needs [`MAX_ENCODED`] bytes for any message.
pub fn encode<T: Serialize>(message: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_FRAME];
    let n = ser::to_slice(message, &mut raw[..MAX_MESSAGE]).map_err(|_| FrameError::TooLong)?;
    let crc = crate::container::crc32(&raw[..n]);
    raw[n..n + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    let stuffed = cobs::encode(&raw[..n + CRC_LEN], out)?;
    if stuffed >= out.len() {
        return Err(FrameError::TooLong);
    }
    out[stuffed] = 0;
    Ok(stuffed + 1)
}

/// Decodes an unstuffed frame (as [`cobs::Decoder`] hands it out): checks the CRC,
/// then the message. The message borrows from `frame`.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a [u8]) -> Result<T, FrameError> {
    let body = check(frame)?;
    // postcard stops where the message ends: bytes after it, under a good CRC, are
    // a message of another shape, not this one.
    match postcard::take_from_bytes(body) {
        Ok((message, [])) => Ok(message),
        _ => Err(FrameError::Malformed),
    }
}

/// The message bytes of an unstuffed frame whose CRC matches.
pub fn check(frame: &[u8]) -> Result<&[u8], FrameError> {
    if frame.len() > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    let Some(body_len) = frame.len().checked_sub(CRC_LEN) else {
        return Err(FrameError::Short);
    };
    let (body, crc) = frame.split_at(body_len);
    let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if crate::container::crc32(body) != stored {
        return Err(FrameError::BadCrc);
    }
    Ok(body)
}

/// Keyframe `i` of a `StreamData` payload (see [`Command::StreamData`]); `None` past
/// its end.
pub fn stream_keyframe(keyframes: &[u8], i: usize) -> Option<[i16; 8]> {
    let at = i.checked_mul(KEYFRAME_LEN)?;
    let bytes = keyframes.get(at..at + KEYFRAME_LEN)?;
    let mut k = [0i16; 8];
    for (c, v) in k.iter_mut().enumerate() {
        *v = i16::from_le_bytes([bytes[2 * c], bytes[2 * c + 1]]);
    }
    Some(k)
}

/// Writes keyframes into a `StreamData` payload; returns the bytes used (fewer
/// keyframes than given if `out` is full).
pub fn put_stream_keyframes(keyframes: &[[i16; 8]], out: &mut [u8]) -> usize {
    let mut n = 0;
    for (k, dst) in keyframes.iter().zip(out.chunks_exact_mut(KEYFRAME_LEN)) {
        for (c, v) in k.iter().enumerate() {
            dst[2 * c..2 * c + 2].copy_from_slice(&v.to_le_bytes());
        }
        n += KEYFRAME_LEN;
    }
    n
}

impl StreamParams {
    /// Checks each field's range (as a stimulus header's).
    pub fn validate(&self) -> Result<(), LinkError> {
        let ok = (1..=crate::stimulus::MAX_KEYFRAME_PERIOD_MS).contains(&self.keyframe_period_ms)
            && self.ramp_ms >= 1
            && (1..=crate::stimulus::MAX_FULL_SCALE_MA).contains(&self.full_scale_ma);
        if ok {
            Ok(())
        } else {
            Err(LinkError::Malformed)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_messages_fit() {
        let bytes = [0xAAu8; MAX_CHUNK];
        let mut wire = [0u8; MAX_ENCODED];
        let big = [
            Request {
                seq: u16::MAX,
                command: Command::BankChunk {
                    offset: u32::MAX,
                    bytes: &bytes,
                },
            },
            Request {
                seq: u16::MAX,
                command: Command::StreamData {
                    index: u32::MAX,
                    keyframes: &bytes,
                },
            },
        ];
        for r in big {
            let n = encode(&r, &mut wire).unwrap();
            assert!(n <= MAX_ENCODED);
        }
        let m = Message::Reply {
            seq: u16::MAX,
            reply: Reply::BankData {
                offset: u32::MAX,
                bytes: &bytes,
            },
        };
        assert!(encode(&m, &mut wire).is_ok());
        let too_big = [0u8; MAX_CHUNK + 40];
        let r = Request {
            seq: 1,
            command: Command::BankChunk {
                offset: 0,
                bytes: &too_big,
            },
        };
        assert_eq!(encode(&r, &mut wire), Err(FrameError::TooLong));
    }

    #[test]
    fn damage_is_caught() {
        let mut wire = [0u8; MAX_ENCODED];
        let n = encode(
            &Request {
                seq: 3,
                command: Command::Play { slot: 2 },
            },
            &mut wire,
        )
        .unwrap();
        let mut raw = [0u8; MAX_FRAME];
        let m = cobs::decode(&wire[..n - 1], &mut raw).unwrap();
        for bit in 0..m * 8 {
            let mut bad = raw;
            bad[bit / 8] ^= 1 << (bit % 8);
            assert_eq!(decode::<Request>(&bad[..m]), Err(FrameError::BadCrc));
        }
        assert_eq!(decode::<Request>(&raw[..3]), Err(FrameError::Short));
        // A good CRC over bytes that are not a request.
        let body = [0x05, 0x7F];
        let mut frame = body.to_vec();
        frame.extend_from_slice(&crate::container::crc32(&body).to_le_bytes());
        assert_eq!(decode::<Request>(&frame), Err(FrameError::Malformed));
    }

    #[test]
    fn trailing_bytes_under_a_good_crc_are_malformed() {
        // `Info` (seq 7) is `07 01`; the same with three bytes after it.
        for (body, ok) in [
            (&[0x07, 0x01][..], true),
            (&[0x07, 0x01, 0x00, 0x00, 0x00], false),
        ] {
            let mut frame = body.to_vec();
            frame.extend_from_slice(&crate::container::crc32(body).to_le_bytes());
            let r = decode::<Request>(&frame);
            if ok {
                assert_eq!(r.map(|r| r.command), Ok(Command::Info));
            } else {
                assert_eq!(r, Err(FrameError::Malformed));
            }
        }
    }

    #[test]
    fn keyframes_round_trip() {
        let k = [[1, -1, 32767, -32768, 0, 5, -5, 300], [0; 8]];
        let mut out = [0u8; 40];
        assert_eq!(put_stream_keyframes(&k, &mut out), 32);
        assert_eq!(stream_keyframe(&out[..32], 0), Some(k[0]));
        assert_eq!(stream_keyframe(&out[..32], 1), Some(k[1]));
        assert_eq!(stream_keyframe(&out[..32], 2), None);
    }
}
