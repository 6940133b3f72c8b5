//! The lock-free links between the link's task (thread mode) and the 1 kHz tick (the
//! timer interrupt): commands in, answers and events out, stream keyframes in; the
//! next slot's player, built by the link's task; the state for `Status`, published
//! by the tick.
//!
//! Single-producer single-consumer, so neither side ever waits for the other: the
//! tick takes at most one command per tick and never blocks on a full queue (an
//! answer that does not fit is dropped; the link drains the queue continuously).
//!
//! What would cost the tick most is done on the link's side. A player is built
//! there (its divisions and first keyframes, more than the rest of a tick) into
//! one of two places; the tick that starts it only swaps the two over and hands it
//! the coils' heat ([`TickPort::take_player`]). A `Status` snapshot is a few words
//! the tick stores on request, which the link turns into the reply (the `status`
//! module).

mod status;

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};
use touch_protocol::link::{LinkError, StreamParams, TickReply};
use touch_protocol::{Player, Thermal};

use status::Published;
pub use status::Snapshot;

/// Commands in flight from the link to the tick (one fewer than this).
pub const CONTROL_DEPTH: usize = 5;
/// Answers and events in flight from the tick to the link (one fewer than this).
pub const ANSWER_DEPTH: usize = 9;
/// Answer places the tick wants free before it takes a command: its reply and
/// what else one tick may tell (a button's gesture, a start, a stop, a limit).
pub const ANSWER_MARGIN: usize = 4;
/// Stream keyframes the device buffers (one fewer than this).
pub const KEYFRAME_DEPTH: usize = 33;

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

/// The slot number a stream's player is staged as, built from its first two
/// keyframes ([`LinkPort::stage`], [`TickPort::take_player`]; bank slots are below
/// [`touch_protocol::bank::MAX_SLOTS`]).
pub const STAGED_STREAM: u8 = 0xFE;
/// The same for a stream that ended after its only keyframe.
pub const STAGED_STREAM_ONE: u8 = 0xFD;

/// No player staged (the low byte of [`Players::state`]).
const NONE_STAGED: u32 = 0;
/// The bit of [`Players::state`] that says which place is the link's.
const LINK_PLACE: u32 = 1 << 8;

/// Two places for a player: the tick's (what plays, or played last) and the
/// link's (the next slot's, built ahead). Each place has one owner at a time, and
/// `state` says which: the link fills its place while no player is staged, then
/// stages it; the tick may then take it (the two places swap owners) or drop it.
struct Players<'a> {
    places: [UnsafeCell<MaybeUninit<Player<'a>>>; 2],
    /// Bits 0-7: the slot staged in the link's place, plus one ([`NONE_STAGED`]:
    /// none, the place is the link's to fill); bit 8 ([`LINK_PLACE`]): which place
    /// is the link's.
    state: AtomicU32,
    /// The slot the tick would like staged next, plus one (0: none).
    wanted: AtomicU32,
}

/// The queues, in a static on the target (split once at boot).
pub struct Channels<'a> {
    control: Queue<Control, CONTROL_DEPTH>,
    answers: Queue<Answer, ANSWER_DEPTH>,
    keyframes: Queue<[i16; 8], KEYFRAME_DEPTH>,
    players: Players<'a>,
    published: Published,
    fed: AtomicU32,
    /// Set by the tick when it queued an answer or wants a player staged, cleared
    /// by the link before it looks: the firmware wakes the link's task on it
    /// instead of polling.
    answered: AtomicBool,
}

impl Default for Channels<'_> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'a> Channels<'a> {
    /// Empty queues, no player.
    pub const fn new() -> Self {
        Channels {
            control: Queue::new(),
            answers: Queue::new(),
            keyframes: Queue::new(),
            players: Players {
                places: [
                    UnsafeCell::new(MaybeUninit::uninit()),
                    UnsafeCell::new(MaybeUninit::uninit()),
                ],
                state: AtomicU32::new(NONE_STAGED),
                wanted: AtomicU32::new(0),
            },
            published: Published::new(),
            fed: AtomicU32::new(0),
            answered: AtomicBool::new(false),
        }
    }

    /// The link's end and the tick's end.
    pub fn split(&mut self) -> (LinkPort<'_, 'a>, TickPort<'_, 'a>) {
        let (control_tx, control_rx) = self.control.split();
        let (answer_tx, answer_rx) = self.answers.split();
        let (key_tx, key_rx) = self.keyframes.split();
        let players = &self.players;
        let published = &self.published;
        let fed = &self.fed;
        let answered = &self.answered;
        (
            LinkPort {
                control: control_tx,
                answers: answer_rx,
                keyframes: key_tx,
                players,
                published,
                fed,
                answered,
            },
            TickPort {
                control: control_rx,
                answers: answer_tx,
                keyframes: key_rx,
                players,
                published,
                fed,
                answered,
            },
        )
    }
}

/// The link's end: sends commands and keyframes, takes answers, builds the next
/// player.
pub struct LinkPort<'q, 'a> {
    control: Producer<'q, Control, CONTROL_DEPTH>,
    answers: Consumer<'q, Answer, ANSWER_DEPTH>,
    keyframes: Producer<'q, [i16; 8], KEYFRAME_DEPTH>,
    players: &'q Players<'a>,
    published: &'q Published,
    fed: &'q AtomicU32,
    answered: &'q AtomicBool,
}

impl<'a> LinkPort<'_, 'a> {
    /// The slot the tick asked to have staged, if any.
    pub fn wanted(&self) -> Option<u8> {
        let w = self.players.wanted.load(Ordering::Acquire);
        w.checked_sub(1).map(|s| s as u8)
    }

    /// The slot whose player is staged, if any.
    pub fn staged(&self) -> Option<u8> {
        let s = self.players.state.load(Ordering::Acquire) & 0xFF;
        s.checked_sub(1).map(|s| s as u8)
    }

    /// Stages the player for `slot` (built by `build`, here, outside the tick) for
    /// the tick to take when it starts `slot`, and makes `slot` the one wanted. A
    /// player staged for another slot is dropped first; one for `slot` is kept.
    /// Nothing is staged if `build` gives none.
    pub fn stage(&mut self, slot: u8, build: impl FnOnce() -> Option<Player<'a>>) {
        let p = self.players;
        p.wanted.store(u32::from(slot) + 1, Ordering::Release);
        let Some(state) = self.take_back(Some(slot)) else {
            return;
        };
        let Some(player) = build() else {
            return;
        };
        let place = usize::from(state & LINK_PLACE != 0);
        // SAFETY: no player is staged, so the link's place is the link's alone: the
        // tick reads a place only while it is its own or staged (see `Players`).
        unsafe { (*p.places[place].get()).write(player) };
        p.state.store(
            (state & LINK_PLACE) | (u32::from(slot) + 1),
            Ordering::Release,
        );
    }

    /// Drops the player staged for `slot`, if that is the one staged: a stream's
    /// player is staged under one tag for every stream, and one left staged (its
    /// stream stopped before it started) must not start the next.
    pub fn unstage(&mut self, slot: u8) {
        if self.staged() == Some(slot) {
            let _ = self.take_back(None);
        }
    }

    /// Takes back the link's place from a staged player (unless it is `keep`'s:
    /// then `None`); the state with none staged.
    fn take_back(&self, keep: Option<u8>) -> Option<u32> {
        let p = self.players;
        let mut state = p.state.load(Ordering::Acquire);
        loop {
            let staged = state & 0xFF;
            if keep.is_some_and(|k| staged == u32::from(k) + 1) {
                return None;
            }
            if staged == NONE_STAGED {
                return Some(state);
            }
            // Take back the place of a player the tick may be taking right now: if
            // it did, `state` changed and this fails.
            match p.state.compare_exchange(
                state,
                state & LINK_PLACE,
                Ordering::AcqRel,
                Ordering::Acquire,
            ) {
                Ok(_) => return Some(state & LINK_PLACE),
                Err(now) => state = now,
            }
        }
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

/// The tick's end: takes commands and keyframes, sends answers, plays the player
/// in its place.
pub struct TickPort<'q, 'a> {
    control: Consumer<'q, Control, CONTROL_DEPTH>,
    answers: Producer<'q, Answer, ANSWER_DEPTH>,
    keyframes: Consumer<'q, [i16; 8], KEYFRAME_DEPTH>,
    players: &'q Players<'a>,
    published: &'q Published,
    fed: &'q AtomicU32,
    answered: &'q AtomicBool,
}

// SAFETY: each port is one end: the places and the published words are shared
// through atomics that say, at every moment, which end may touch which place (see
// `Players`, `Published`), so an end may move to another context (the tick's
// interrupt, the link's task) as long as the players it carries may.
unsafe impl<'a> Send for TickPort<'_, 'a> where Player<'a>: Send {}
// SAFETY: as for `TickPort`.
unsafe impl<'a> Send for LinkPort<'_, 'a> where Player<'a>: Send {}

impl core::fmt::Debug for TickPort<'_, '_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TickPort")
    }
}

impl<'a> TickPort<'_, 'a> {
    /// The next command, if any.
    pub fn next_control(&mut self) -> Option<Control> {
        self.control.dequeue()
    }

    /// The next command, left in the queue.
    pub fn peek_control(&self) -> Option<&Control> {
        self.control.peek()
    }

    /// The tick's place: 0 or 1.
    fn own_place(&self) -> usize {
        usize::from(self.players.state.load(Ordering::Relaxed) & LINK_PLACE == 0)
    }

    /// True when the player for `slot` is staged.
    pub fn staged(&self, slot: u8) -> bool {
        self.players.state.load(Ordering::Acquire) & 0xFF == u32::from(slot) + 1
    }

    /// Asks the link to stage the player for `slot` (it wakes for it).
    pub fn want(&mut self, slot: u8) {
        self.players
            .wanted
            .store(u32::from(slot) + 1, Ordering::Release);
        self.answered.store(true, Ordering::Release);
    }

    /// Makes the staged player for `slot` the tick's, starting from `thermal`
    /// ([`Player::start_from`]), and gives the link the tick's old place: a swap,
    /// the player is not copied. False (and nothing changed) if another or none is
    /// staged. The player that was in the tick's place must be done with.
    pub fn take_player(&mut self, slot: u8, thermal: &Thermal) -> bool {
        let state = self.players.state.load(Ordering::Acquire);
        if state & 0xFF != u32::from(slot) + 1 {
            return false;
        }
        // The staged place becomes the tick's: the link's is now the other one.
        self.players
            .state
            .store((state & LINK_PLACE) ^ LINK_PLACE, Ordering::Release);
        self.player().start_from(thermal);
        true
    }

    /// Puts `player` (built in the tick: a stream's) in the tick's place.
    pub fn put_player(&mut self, player: Player<'a>) {
        let place = self.own_place();
        // SAFETY: the tick's place is the tick's alone (see `Players`).
        unsafe { (*self.players.places[place].get()).write(player) };
    }

    /// The player in the tick's place. Only after [`TickPort::take_player`] or
    /// [`TickPort::put_player`] put one there.
    pub fn player(&mut self) -> &mut Player<'a> {
        let place = self.own_place();
        // SAFETY: the tick's place is the tick's alone (see `Players`), and the
        // caller put a player there (the controller asks only while one plays).
        unsafe { (*self.players.places[place].get()).assume_init_mut() }
    }

    /// The player in the tick's place (as [`TickPort::player`]).
    pub fn player_ref(&self) -> &Player<'a> {
        let place = self.own_place();
        // SAFETY: as for `player`.
        unsafe { (*self.players.places[place].get()).assume_init_ref() }
    }

    /// Free places in the answer queue: the tick takes a command only while its
    /// reply and the events of the same tick fit ([`ANSWER_MARGIN`]), so that a
    /// link slow to drain the queue holds commands back instead of losing replies.
    pub fn answer_room(&self) -> usize {
        self.answers.capacity() - self.answers.len()
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
