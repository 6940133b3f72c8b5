//! The messages: what the host asks ([`Request`]) and what the device says
//! ([`Message`]: replies, refusals and events). `SPEC.md` ("Link") gives every byte.

use serde::{Deserialize, Serialize};

use crate::link::{FrameError, PlayReply, StopReply, StreamBeginReply};
use crate::Limits;

/// One request from the host: a sequence number the reply echoes, and the command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Request<'a> {
    /// Chosen by the host (an incrementing counter); echoed by the reply or refusal.
    pub seq: u16,
    /// What to do.
    #[serde(borrow)]
    pub command: Command<'a>,
}

/// What the host asks of the device. Every command gets exactly one
/// [`Message::Reply`] (the variant of [`Reply`] with the same name) or one
/// [`Message::Refused`], with the request's `seq`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command<'a> {
    /// Opens a session: the host's link version. A device of another version refuses
    /// it ([`LinkError::UnsupportedVersion`], with its own).
    Hello {
        /// [`crate::link::VERSION`] of the host.
        version: u16,
    },
    /// The device, its limits and its bank.
    Info,
    /// One slot of the bank: name and duration.
    Slot {
        /// Slot index, from 0.
        slot: u8,
    },
    /// The device's state now: what plays, the coils' heat, the last fault.
    Status,
    /// Reads bytes of the bank region (at most [`crate::link::MAX_CHUNK`]).
    BankRead {
        /// Offset from the start of the region.
        offset: u32,
        /// Bytes to read.
        len: u16,
    },
    /// Starts an upload of a bank image of `len` bytes whose CRC-32 is `crc`: stops
    /// nothing (refused while something plays), erases the bank region.
    BankBegin {
        /// Bytes of the whole image.
        len: u32,
        /// CRC-32/ISO-HDLC of the whole image (all `len` bytes).
        crc: u32,
    },
    /// The image's bytes at `offset`, in order: `offset` is where the last chunk
    /// ended (a chunk sent again, equal to what was written, is acknowledged again).
    BankChunk {
        /// Offset of the first byte in the image.
        offset: u32,
        /// At most [`crate::link::MAX_CHUNK`] bytes.
        bytes: &'a [u8],
    },
    /// Checks the uploaded image (length, CRC, bank format, every slot's layout) and
    /// makes it the bank. The device then restarts into it.
    BankCommit,
    /// Abandons an upload; the region stays erased (the built-in bank plays).
    BankAbort,
    /// Plays a slot, as a press on its button would (a playing slot ramps down first).
    Play {
        /// Slot index.
        slot: u8,
    },
    /// Stops what plays (a slot or a stream): the outputs ramp to 0 A.
    Stop,
    /// Prepares a stream: keyframes sent while they play.
    StreamBegin(StreamParams),
    /// Keyframes of the stream, in order from `index`; the first chunk starts it.
    StreamData {
        /// Index of the first keyframe in the stream (0 for the first chunk).
        index: u32,
        /// Keyframes, [`crate::link::KEYFRAME_LEN`] bytes each: eight i16 LE,
        /// channel order, Q15 of the stream's full scale.
        keyframes: &'a [u8],
    },
    /// The stream is complete: it plays out what the device holds, then ramps to 0 A.
    StreamEnd,
}

/// How a stream plays: the keyframe spacing, the ramp, the full scale and the
/// limits it was made for (the device enforces the stricter of these and its own).
pub use crate::player::LiveParams as StreamParams;

/// A message from the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message<'a> {
    /// The answer to the request `seq`.
    Reply {
        /// The request's sequence number.
        seq: u16,
        /// The answer.
        #[serde(borrow)]
        reply: Reply<'a>,
    },
    /// The request `seq` was refused; nothing changed.
    Refused {
        /// The request's sequence number.
        seq: u16,
        /// Why.
        error: LinkError,
    },
    /// Something happened on the device, at its 1 kHz `tick` (ms since power-up,
    /// wrapping at 2^32).
    Event {
        /// When.
        tick: u32,
        /// What.
        event: Event,
    },
    /// A frame arrived that could not be read (its `seq` is unknown): nothing was done.
    Unreadable(FrameError),
}

/// The answer to each [`Command`], same names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reply<'a> {
    /// The device speaks the host's version.
    Hello {
        /// [`crate::link::VERSION`] of the device.
        version: u16,
        /// The firmware's version.
        firmware: &'a str,
    },
    /// The device.
    #[serde(borrow)]
    Info(Info<&'a str>),
    /// One slot.
    #[serde(borrow)]
    Slot(SlotInfo<&'a str>),
    /// The device's state.
    Status(StatusReport),
    /// Bytes of the bank region.
    BankData {
        /// Offset of the first byte.
        offset: u32,
        /// The bytes (fewer than asked at the region's end).
        bytes: &'a [u8],
    },
    /// The region is erased and ready for `len` bytes.
    BankBegin {
        /// Bytes expected.
        len: u32,
    },
    /// The chunk is written; `next` is the offset of the next one.
    BankChunk {
        /// Bytes of the image written so far.
        next: u32,
    },
    /// The image is the bank; the device restarts into it after this reply.
    BankCommit {
        /// Its CRC-32.
        crc: u32,
        /// Its number of slots.
        slots: u8,
    },
    /// The upload is abandoned.
    BankAbort,
    /// The slot plays (or waits for a ramp down first).
    Play(PlayReply),
    /// The ramp to 0 A began (or nothing played).
    Stop(StopReply),
    /// The stream is ready; send keyframes.
    StreamBegin(StreamBeginReply),
    /// Keyframes taken.
    StreamData {
        /// Index of the next keyframe the device expects.
        next: u32,
        /// Free places in the device's buffer after this chunk.
        room: u16,
    },
    /// The stream plays out and ends.
    StreamEnd,
}

/// The device: versions, layout, limits and bank. Its text is `S`: `&str` on the wire
/// ([`Reply::Info`]), an owned string where a host keeps it ([`Info::map_text`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Info<S> {
    /// [`crate::link::VERSION`].
    pub link_version: u16,
    /// The firmware's version (its Cargo version).
    pub firmware: S,
    /// The actuator layout the firmware drives (a layout file's `id`).
    pub layout: S,
    /// The layout's geometry hash: a stimulus or bank for another is refused.
    pub layout_hash: u32,
    /// Current at the outputs' full scale, mA.
    pub full_scale_ma: u16,
    /// The device's hard limits.
    pub limits: Limits,
    /// Largest frame the device takes, bytes of postcard message.
    pub max_message: u16,
    /// Largest `BankChunk`/`BankRead`/`StreamData` payload, bytes.
    pub max_chunk: u16,
    /// Bytes of the bank region.
    pub bank_capacity: u32,
    /// The bank the device plays.
    pub bank: BankState,
}

/// Which bank the device plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BankState {
    /// The bank in the bank region.
    Flashed(BankSummary),
    /// The region is erased: the bank built into the firmware.
    Builtin(BankSummary),
    /// The bank in the region was refused; nothing plays. `blinks` is its LED code.
    Refused {
        /// The LED blink code (2 empty, 3 not a bank, 4 CRC, 5 malformed, 6 another
        /// layout).
        blinks: u8,
    },
}

/// A bank, in short.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BankSummary {
    /// Bytes of the image.
    pub len: u32,
    /// The CRC-32 stored in the image's last four bytes (over every byte before
    /// them): the one the boot checked, which tells banks apart. (The CRC-32 of a
    /// whole intact image, as [`Command::BankBegin`] takes it, is the same constant
    /// for every bank.)
    pub crc: u32,
    /// Number of slots.
    pub slots: u8,
}

/// One slot of the bank. Its text is `S`, as [`Info`]'s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotInfo<S> {
    /// Its index.
    pub slot: u8,
    /// The stimulus's name.
    pub name: S,
    /// The keyframed signal's length, ms.
    pub duration_ms: u32,
    /// Playback length with the final ramp, ms.
    pub playback_ms: u32,
    /// False if the firmware refuses it (compiled for another layout).
    pub playable: bool,
}

impl<S> Info<S> {
    /// The same with its text turned by `f` (`str::to_owned` keeps it past the frame).
    pub fn map_text<T>(self, mut f: impl FnMut(S) -> T) -> Info<T> {
        // Every field named, without `..`: one added must be carried here too.
        let Info {
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
        } = self;
        Info {
            link_version,
            firmware: f(firmware),
            layout: f(layout),
            layout_hash,
            full_scale_ma,
            limits,
            max_message,
            max_chunk,
            bank_capacity,
            bank,
        }
    }
}

impl<S> SlotInfo<S> {
    /// The same with its name turned by `f`.
    pub fn map_text<T>(self, f: impl FnOnce(S) -> T) -> SlotInfo<T> {
        let SlotInfo {
            slot,
            name,
            duration_ms,
            playback_ms,
            playable,
        } = self;
        SlotInfo {
            slot,
            name: f(name),
            duration_ms,
            playback_ms,
            playable,
        }
    }
}

/// What plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Source {
    /// A bank slot.
    Slot(u8),
    /// The host's stream.
    Stream,
}

/// The device's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusReport {
    /// The tick the state was read at.
    pub tick: u32,
    /// What plays or ramps down, if anything.
    pub playing: Option<Source>,
    /// True while it ramps down.
    pub stopping: bool,
    /// The slot a short press plays.
    pub selected: u8,
    /// Each channel's heat, per mille of the I^2 t budget a start of the selected
    /// slot is judged by (the stricter of its own and the device's): such a start is
    /// refused above 500, with the per mille this gives.
    pub heat_permille: [u16; 8],
    /// Idle milliseconds until a start of the selected slot is accepted (0: now).
    pub cooldown_ms: u32,
    /// Limit hits since power-up.
    pub faults: u16,
    /// The last one, if any.
    pub last_fault: Option<FaultRecord>,
    /// Bytes received of an upload in progress, if any.
    pub upload: Option<u32>,
}

/// A limit hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    /// When.
    pub tick: u32,
    /// What was playing.
    pub source: Source,
    /// Which limit.
    pub kind: Limit,
    /// The first channel that hit it.
    pub channel: u8,
}

/// A safety limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Limit {
    /// Peak current.
    Peak,
    /// Slew per ms.
    Slew,
    /// The thermal I^2 t budget.
    Thermal,
}

impl From<crate::player::LimitKind> for Limit {
    fn from(k: crate::player::LimitKind) -> Self {
        use crate::player::LimitKind;
        match k {
            LimitKind::Peak => Limit::Peak,
            LimitKind::Slew => Limit::Slew,
            LimitKind::Thermal => Limit::Thermal,
        }
    }
}

/// A button gesture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Gesture {
    /// A short press of the play button.
    Toggle,
    /// A long press: select the next slot.
    Next,
    /// A press of the button of this slot.
    Slot(u8),
}

/// Why a stream stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StreamStop {
    /// No data for [`crate::link::STREAM_DEADLINE_MS`]: the host is gone.
    Deadline,
    /// A keyframe was due that had not arrived.
    Underrun,
    /// The host ended it ([`Command::StreamEnd`]) and it played out.
    Ended,
}

/// Something that happened on the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// A button gesture (what it does follows as other events).
    Button(Gesture),
    /// The first frame of a slot or a stream went out.
    Started(Source),
    /// The outputs began ramping to 0 A (a stop, or the end of a stream).
    Stopping(Source),
    /// Playback ended: every output is at 0 A.
    Finished(Source),
    /// A limit was hit; the outputs ramp to 0 A.
    LimitHit {
        /// What was playing.
        source: Source,
        /// Which limit.
        kind: Limit,
        /// The first channel that hit it.
        channel: u8,
    },
    /// A start was refused: a coil is too hot.
    TooHot {
        /// What was to start.
        source: Source,
        /// The hottest channel.
        channel: u8,
        /// Its heat, per mille of the budget.
        permille: u16,
        /// Idle milliseconds until a start is accepted.
        cooldown_ms: u32,
    },
    /// The selection moved (a long press).
    Selected(u8),
    /// A slot that the firmware refuses was asked to play (another layout).
    BadSlot(u8),
    /// The stream stopped; the outputs ramp to 0 A.
    StreamStopped(StreamStop),
}

/// Why a command was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError {
    /// The command did not decode (unknown variant, bad field) or broke a rule of
    /// its own (a length past [`crate::link::MAX_CHUNK`], stream bytes not a whole
    /// number of keyframes, stream parameters out of range).
    Malformed,
    /// The device speaks another link version.
    UnsupportedVersion {
        /// The device's version.
        device: u16,
    },
    /// No such slot in the bank.
    NoSuchSlot {
        /// Asked for.
        slot: u8,
        /// Slots in the bank.
        slots: u8,
    },
    /// The slot is refused by the firmware (compiled for another layout).
    BadSlot {
        /// The slot.
        slot: u8,
    },
    /// A coil is too hot to start; nothing plays.
    TooHot {
        /// The hottest channel.
        channel: u8,
        /// Its heat, per mille of the budget.
        permille: u16,
        /// Idle milliseconds until a start is accepted.
        cooldown_ms: u32,
    },
    /// Not now: something plays, an upload runs, or a stream is in the way.
    Busy(Busy),
    /// No playable bank (the region was refused or an upload erased it).
    NoBank,
    /// A bank chunk, commit or abort without a [`Command::BankBegin`] first.
    NoUpload,
    /// A chunk at another offset than where the last one ended.
    OutOfOrder {
        /// The offset the device expects.
        expected: u32,
    },
    /// An offset or length outside the bank region (or the announced image).
    OutOfRange,
    /// The image's CRC-32 is not the one announced.
    BadCrc {
        /// Announced by [`Command::BankBegin`].
        expected: u32,
        /// Computed over the bytes received.
        computed: u32,
    },
    /// The image was compiled for another layout (its geometry hash is not the
    /// firmware's); the region is erased.
    WrongLayout {
        /// The first slot compiled for another layout (a bank holds one layout: 0).
        slot: u8,
    },
    /// The image is not a valid bank; the region is erased. `blinks` is the LED code
    /// a boot would show for it.
    BadBank {
        /// The boot's LED code (3 not a bank or wrong version, 4 CRC, 5 malformed).
        blinks: u8,
    },
    /// The flash did not erase or program (the region is left erased or refused).
    Flash,
    /// Stream data without a [`Command::StreamBegin`], or for a stream that stopped.
    NoStream,
    /// Stream keyframes not in order.
    StreamGap {
        /// The index the device expects.
        expected: u32,
    },
    /// More keyframes than the device's buffer has room for.
    StreamFull {
        /// Free places.
        room: u16,
    },
    /// The device's queue of commands for the tick was full (four wait): the host
    /// sent faster than it read their replies. Nothing was done; the request may
    /// be sent again once a reply came.
    QueueFull,
}

/// What is in the way of a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Busy {
    /// Something plays (an upload needs the outputs at rest).
    Playing,
    /// An upload is in progress.
    Uploading,
    /// A stream plays (a slot cannot start over it; stop it first).
    Streaming,
}
