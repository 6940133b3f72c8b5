//! The replies to the commands that start and stop playback (`Play`, `Stop`,
//! `StreamBegin`, `StreamEnd`): their payloads, defined once, which [`Reply`]'s
//! variants carry, and [`TickReply`], the same four as a small `Copy` enum that owns
//! nothing, for a device whose 1 kHz tick answers them through a queue.
//!
//! A payload struct in a newtype variant is the same postcard bytes as a struct
//! variant with its fields (the variant's index, then the fields in order): the
//! golden tests pin them.

use serde::{Deserialize, Serialize};

use super::{Reply, Source};

/// [`Reply::Play`]: the slot plays, its first frame at `tick` (a slot already
/// playing ramps down first; then `tick` is when that ramp down began, and
/// [`super::Event::Started`] follows with the first frame's tick).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlayReply {
    /// The slot.
    pub slot: u8,
    /// The tick of the first frame, or of the start of the ramp down before it.
    pub tick: u32,
    /// True if the slot starts at `tick`; false if it waits for a ramp down.
    pub now: bool,
}

/// [`Reply::Stop`]: the ramp to 0 A began at `tick` (or nothing played: `source` is
/// `None`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StopReply {
    /// What was stopped.
    pub source: Option<Source>,
    /// The tick the ramp down began.
    pub tick: u32,
}

/// [`Reply::StreamBegin`]: the stream is ready; send keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StreamBeginReply {
    /// Keyframes the device buffers ahead of the one playing.
    pub capacity: u16,
}

/// The replies a device's tick gives, as [`Reply`] carries them: small and `Copy`,
/// so that an interrupt can queue one without borrowing or copying a whole
/// [`Reply`] (whose other variants hold text and bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TickReply {
    /// [`Reply::Play`].
    Play(PlayReply),
    /// [`Reply::Stop`].
    Stop(StopReply),
    /// [`Reply::StreamBegin`].
    StreamBegin(StreamBeginReply),
    /// [`Reply::StreamEnd`].
    StreamEnd,
}

impl From<TickReply> for Reply<'static> {
    fn from(r: TickReply) -> Self {
        match r {
            TickReply::Play(p) => Reply::Play(p),
            TickReply::Stop(s) => Reply::Stop(s),
            TickReply::StreamBegin(b) => Reply::StreamBegin(b),
            TickReply::StreamEnd => Reply::StreamEnd,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::Message;

    /// Each tick reply, as the device sends it with `seq` 300, is the bytes the
    /// golden tests pin for the wire's reply (tests/link_golden.rs).
    #[test]
    fn each_tick_reply_is_its_wire_replys_bytes() {
        let cases = [
            (
                TickReply::Play(PlayReply {
                    slot: 3,
                    tick: 123_456,
                    now: true,
                }),
                &[0x00, 0xAC, 0x02, 0x09, 0x03, 0xC0, 0xC4, 0x07, 0x01][..],
            ),
            (
                TickReply::Stop(StopReply {
                    source: Some(Source::Stream),
                    tick: 5,
                }),
                &[0x00, 0xAC, 0x02, 0x0A, 0x01, 0x01, 0x05],
            ),
            (
                TickReply::Stop(StopReply {
                    source: None,
                    tick: 128,
                }),
                &[0x00, 0xAC, 0x02, 0x0A, 0x00, 0x80, 0x01],
            ),
            (
                TickReply::StreamBegin(StreamBeginReply { capacity: 32 }),
                &[0x00, 0xAC, 0x02, 0x0B, 0x20],
            ),
            (TickReply::StreamEnd, &[0x00, 0xAC, 0x02, 0x0D]),
        ];
        for (tick_reply, want) in cases {
            let m = Message::Reply {
                seq: 300,
                reply: tick_reply.into(),
            };
            let mut buf = [0u8; 16];
            let n = crate::link::ser::to_slice(&m, &mut buf).unwrap();
            assert_eq!(&buf[..n], want, "{tick_reply:?}");
            let back: Message<'_> = postcard::from_bytes(&buf[..n]).unwrap();
            assert_eq!(back, m, "{tick_reply:?}");
        }
    }
}
