//! The lock-free queues between the link (thread mode) and the 1 kHz tick (the
//! timer interrupt): commands in, answers and events out, stream keyframes in.
//!
//! Single-producer single-consumer queues, so neither side ever waits for the other:
//! the tick takes at most one command per tick and never blocks on a full queue (an
//! answer that does not fit is dropped; the link drains the queue continuously).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};
use touch_protocol::link::{FaultRecord, LinkError, Reply, Source, StreamParams};
use touch_protocol::Thermal;

/// Commands in flight from the link to the tick (one fewer than this).
pub const CONTROL_DEPTH: usize = 5;
/// Answers and events in flight from the tick to the link (one fewer than this).
pub const ANSWER_DEPTH: usize = 9;
/// Stream keyframes the device buffers (one fewer than this).
pub const KEYFRAME_DEPTH: usize = 33;
/// `Status` snapshots in flight (one fewer than this).
pub const SNAPSHOT_DEPTH: usize = 3;

/// What the link asks of the tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    /// Play a slot.
    Play {
        /// The request's sequence number.
        seq: u16,
        /// The slot.
        slot: u8,
    },
    /// Stop what plays.
    Stop {
        /// The request's sequence number.
        seq: u16,
    },
    /// Report the state.
    Status {
        /// The request's sequence number.
        seq: u16,
    },
    /// Arm a stream.
    StreamBegin {
        /// The request's sequence number.
        seq: u16,
        /// How it plays.
        params: StreamParams,
    },
    /// The stream is complete.
    StreamEnd {
        /// The request's sequence number.
        seq: u16,
    },
    /// An upload takes the bank region: refuse if anything plays, else start nothing
    /// from the bank any more (until the restart that follows the upload).
    Lock {
        /// The request's sequence number.
        seq: u16,
    },
}

/// The device's state for a `Status` reply, raw (the link turns heat into per mille).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Snapshot {
    /// The tick it was taken at.
    pub tick: u32,
    /// What plays.
    pub playing: Option<touch_protocol::link::Source>,
    /// Ramping down.
    pub stopping: bool,
    /// The selected slot.
    pub selected: u8,
    /// The coils' heat.
    pub thermal: Thermal,
    /// Limit hits since power-up.
    pub faults: u16,
    /// The last one.
    pub last_fault: Option<FaultRecord>,
}

/// The tick's replies: the variants of [`Reply`] it gives, small (an answer is
/// copied into the queue in the tick; the snapshot of a `Status` travels apart).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TickReply {
    /// [`Reply::Play`].
    Play {
        /// The slot.
        slot: u8,
        /// The tick of its first frame, or of the ramp down before it.
        tick: u32,
        /// True if it starts at `tick`.
        now: bool,
    },
    /// [`Reply::Stop`].
    Stop {
        /// What was stopped.
        source: Option<Source>,
        /// The tick the ramp down began.
        tick: u32,
    },
    /// [`Reply::StreamBegin`].
    StreamBegin {
        /// Keyframes the device buffers.
        capacity: u16,
    },
    /// [`Reply::StreamEnd`].
    StreamEnd,
}

impl From<TickReply> for Reply<'static> {
    fn from(r: TickReply) -> Self {
        match r {
            TickReply::Play { slot, tick, now } => Reply::Play { slot, tick, now },
            TickReply::Stop { source, tick } => Reply::Stop { source, tick },
            TickReply::StreamBegin { capacity } => Reply::StreamBegin { capacity },
            TickReply::StreamEnd => Reply::StreamEnd,
        }
    }
}

/// What the tick tells the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// A reply to the request `seq`.
    Reply(u16, TickReply),
    /// The state for the `Status` request `seq` is the next snapshot
    /// ([`LinkPort::snapshot`]).
    Status(u16),
    /// The request `seq` was refused.
    Refused(u16, LinkError),
    /// The bank is locked for the upload of request `seq`.
    Locked(u16),
    /// An event at a tick.
    Event(u32, touch_protocol::link::Event),
}

/// The queues, in a static on the target (split once at boot).
pub struct Channels {
    control: Queue<Control, CONTROL_DEPTH>,
    answers: Queue<Answer, ANSWER_DEPTH>,
    keyframes: Queue<[i16; 8], KEYFRAME_DEPTH>,
    snapshots: Queue<Snapshot, SNAPSHOT_DEPTH>,
    fed: AtomicU32,
    /// Set by the tick when it queued an answer, cleared by the link before it
    /// drains them: the firmware wakes the link's task on it instead of polling.
    answered: AtomicBool,
}

impl Default for Channels {
    fn default() -> Self {
        Self::new()
    }
}

impl Channels {
    /// Empty queues.
    pub const fn new() -> Self {
        Channels {
            control: Queue::new(),
            answers: Queue::new(),
            keyframes: Queue::new(),
            snapshots: Queue::new(),
            fed: AtomicU32::new(0),
            answered: AtomicBool::new(false),
        }
    }

    /// The link's end and the tick's end.
    pub fn split(&mut self) -> (LinkPort<'_>, TickPort<'_>) {
        let (control_tx, control_rx) = self.control.split();
        let (answer_tx, answer_rx) = self.answers.split();
        let (key_tx, key_rx) = self.keyframes.split();
        let (snap_tx, snap_rx) = self.snapshots.split();
        let fed = &self.fed;
        let answered = &self.answered;
        (
            LinkPort {
                control: control_tx,
                answers: answer_rx,
                keyframes: key_tx,
                snapshots: snap_rx,
                fed,
                answered,
            },
            TickPort {
                control: control_rx,
                answers: answer_tx,
                keyframes: key_rx,
                snapshots: snap_tx,
                fed,
                answered,
            },
        )
    }
}

/// The link's end: sends commands and keyframes, takes answers.
pub struct LinkPort<'a> {
    control: Producer<'a, Control, CONTROL_DEPTH>,
    answers: Consumer<'a, Answer, ANSWER_DEPTH>,
    keyframes: Producer<'a, [i16; 8], KEYFRAME_DEPTH>,
    snapshots: Consumer<'a, Snapshot, SNAPSHOT_DEPTH>,
    fed: &'a AtomicU32,
    answered: &'a AtomicBool,
}

impl LinkPort<'_> {
    /// The snapshot of the oldest unanswered [`Answer::Status`].
    pub fn snapshot(&mut self) -> Option<Snapshot> {
        self.snapshots.dequeue()
    }

    /// Queues a command; gives it back if the queue is full.
    pub fn send(&mut self, c: Control) -> Result<(), Control> {
        self.control.enqueue(c)
    }

    /// The next answer or event, if any.
    pub fn receive(&mut self) -> Option<Answer> {
        // Cleared before the queue is read: an answer queued after this sets it again.
        self.answered.store(false, Ordering::Release);
        self.answers.dequeue()
    }

    /// Free places for stream keyframes.
    pub fn keyframe_room(&self) -> usize {
        self.keyframes.capacity() - self.keyframes.len()
    }

    /// Queues a stream keyframe (call [`LinkPort::fed`] after a chunk).
    pub fn push_keyframe(&mut self, k: [i16; 8]) -> Result<(), [i16; 8]> {
        self.keyframes.enqueue(k)
    }

    /// Tells the tick that stream data arrived (the deadline starts again).
    pub fn fed(&self) {
        self.fed.fetch_add(1, Ordering::Release);
    }
}

/// The tick's end: takes commands and keyframes, sends answers.
pub struct TickPort<'a> {
    control: Consumer<'a, Control, CONTROL_DEPTH>,
    answers: Producer<'a, Answer, ANSWER_DEPTH>,
    keyframes: Consumer<'a, [i16; 8], KEYFRAME_DEPTH>,
    snapshots: Producer<'a, Snapshot, SNAPSHOT_DEPTH>,
    fed: &'a AtomicU32,
    answered: &'a AtomicBool,
}

impl core::fmt::Debug for TickPort<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TickPort")
    }
}

impl TickPort<'_> {
    /// The next command, if any.
    pub fn next_control(&mut self) -> Option<Control> {
        self.control.dequeue()
    }

    /// Sends an answer; dropped if the queue is full.
    pub fn send(&mut self, a: Answer) {
        let _ = self.answers.enqueue(a);
        self.answered.store(true, Ordering::Release);
    }

    /// True once an answer was sent and the link has not looked since (the firmware
    /// wakes the link's task on it).
    pub fn answered(&self) -> bool {
        self.answered.load(Ordering::Acquire)
    }

    /// Queues a snapshot for a `Status`; false if the link has not taken the last
    /// ones yet.
    pub fn send_snapshot(&mut self, s: Snapshot) -> bool {
        self.snapshots.enqueue(s).is_ok()
    }

    /// The next stream keyframe, if any.
    pub fn next_keyframe(&mut self) -> Option<[i16; 8]> {
        self.keyframes.dequeue()
    }

    /// Stream keyframes waiting.
    pub fn keyframes_ready(&self) -> usize {
        self.keyframes.len()
    }

    /// Stream keyframes the queue holds at most.
    pub fn keyframe_capacity(&self) -> u16 {
        self.keyframes.capacity() as u16
    }

    /// The count of stream data arrivals (changes when data arrived).
    pub fn fed(&self) -> u32 {
        self.fed.load(Ordering::Acquire)
    }
}
