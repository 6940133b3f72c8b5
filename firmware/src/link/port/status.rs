//! The state for a `Status` reply, published by the tick as words and read back
//! whole by the link: a sequence count, odd while the tick writes, tells the link
//! whether it read a torn copy (the tick never waits, the link reads again).

use core::sync::atomic::{fence, AtomicU32, Ordering};

use touch_protocol::link::{FaultRecord, Limit, Source};
use touch_protocol::{Limits, Thermal, CHANNELS};

use super::{LinkPort, TickPort};

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
    /// The limits a start of the selected slot is judged by
    /// ([`crate::control::Controller::start_limits`]): `Status` reports the heat
    /// against them, as a refused start does.
    pub start_limits: Limits,
    /// The coils' heat.
    pub thermal: Thermal,
    /// Limit hits since power-up.
    pub faults: u16,
    /// The last one.
    pub last_fault: Option<FaultRecord>,
}

/// [`Source`] in 9 bits (0: none).
fn source_code(s: Option<Source>) -> u32 {
    match s {
        None => 0,
        Some(Source::Stream) => 1,
        Some(Source::Slot(slot)) => 2 + u32::from(slot),
    }
}

fn source_from(code: u32) -> Option<Source> {
    match code & 0x1FF {
        0 => None,
        1 => Some(Source::Stream),
        c => Some(Source::Slot((c - 2) as u8)),
    }
}

impl Snapshot {
    /// The snapshot the tick published as words (see [`TickPort::publish_status`]).
    fn from_words(w: &[u32; SNAPSHOT_WORDS]) -> Snapshot {
        let last_fault = (w[2] & 1 << 16 != 0).then(|| FaultRecord {
            tick: w[3],
            source: source_from(w[4]).unwrap_or(Source::Stream),
            kind: match (w[4] >> 9) & 3 {
                0 => Limit::Peak,
                1 => Limit::Slew,
                _ => Limit::Thermal,
            },
            channel: (w[4] >> 16) as u8,
        });
        Snapshot {
            tick: w[0],
            playing: source_from(w[1]),
            stopping: w[1] & 1 << 9 != 0,
            selected: (w[1] >> 16) as u8,
            start_limits: Limits {
                peak_ma: w[21] as u16,
                slew_ma_per_ms: (w[21] >> 16) as u16,
                continuous_ma: w[22] as u16,
                i2t_budget_ma2s: w[23],
            },
            thermal: Thermal::from_heat_ma2ms(core::array::from_fn(|c| {
                u64::from(w[5 + 2 * c]) | u64::from(w[6 + 2 * c]) << 32
            })),
            faults: w[2] as u16,
            last_fault,
        }
    }
}

/// The state for a `Status` reply as words: the tick stores them on request, the
/// link reads them back whole (the sequence count, odd while the tick writes, says
/// whether it wrote in between).
pub(super) struct Published {
    seq: AtomicU32,
    words: [AtomicU32; SNAPSHOT_WORDS],
}

/// Words of a published [`Snapshot`]: the tick, what plays and the selection, the
/// fault count and the last fault (three words), each channel's heat (two words
/// each), the selected slot's start limits (three words).
const SNAPSHOT_WORDS: usize = 5 + 2 * CHANNELS + 3;

impl Published {
    /// Nothing published yet.
    pub(super) const fn new() -> Self {
        Published {
            seq: AtomicU32::new(0),
            words: [const { AtomicU32::new(0) }; SNAPSHOT_WORDS],
        }
    }
}

impl LinkPort<'_, '_> {
    /// The state the tick published for the last
    /// [`Answer::Status`](super::Answer::Status) (or a later one, if the tick
    /// answered another `Status` meanwhile).
    pub fn snapshot(&self) -> Snapshot {
        let p = self.published;
        loop {
            let before = p.seq.load(Ordering::Acquire);
            let words: [u32; SNAPSHOT_WORDS] =
                core::array::from_fn(|i| p.words[i].load(Ordering::Relaxed));
            fence(Ordering::Acquire);
            // The tick interrupts this task, never the reverse: an odd count is
            // never seen here, a changed one means it wrote in between.
            if before & 1 == 0 && p.seq.load(Ordering::Relaxed) == before {
                return Snapshot::from_words(&words);
            }
        }
    }
}

/// Stores published words (the tick's side), with the sequence count odd meanwhile.
#[inline(always)]
fn write_words(p: &Published, write: impl FnOnce(&[AtomicU32; SNAPSHOT_WORDS])) {
    let seq = p.seq.load(Ordering::Relaxed);
    p.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
    fence(Ordering::Release);
    write(&p.words);
    p.seq.store(seq.wrapping_add(2), Ordering::Release);
}

impl TickPort<'_, '_> {
    /// Publishes the state for a `Status` reply (read back by
    /// [`LinkPort::snapshot`], with the faults [`TickPort::publish_faults`] stored
    /// last): a store per word, no copy of a snapshot. The heat is `idle`'s, or,
    /// with `idle` none, that of the player in the tick's place. Inlined into its
    /// one caller, the tick's: a call of its own costs flash and the tick time.
    #[inline(always)]
    pub fn publish_status(
        &mut self,
        tick: u32,
        playing: Option<Source>,
        stopping: bool,
        selected: u8,
        start_limits: &Limits,
        idle: Option<&Thermal>,
    ) {
        // The player only when something plays: the place holds none before that.
        let player = match idle {
            Some(_) => None,
            None => Some(self.player_ref()),
        };
        let heat = |c: usize| match (idle, player) {
            (Some(t), _) => t.heat_ma2ms()[c],
            (None, Some(p)) => p.thermal().heat_ma2ms()[c],
            (None, None) => 0,
        };
        write_words(self.published, |words| {
            let w = |i: usize, v: u32| words[i].store(v, Ordering::Relaxed);
            w(0, tick);
            w(
                1,
                source_code(playing) | u32::from(stopping) << 9 | u32::from(selected) << 16,
            );
            // Unrolled, a channel's heat read just before its words are stored: as a
            // loop, or from a copy of the whole state, it costs the tick some 40 to
            // 60 instructions more.
            let put = |c: usize| {
                let h = heat(c);
                w(5 + 2 * c, h as u32);
                w(6 + 2 * c, (h >> 32) as u32);
            };
            put(0);
            put(1);
            put(2);
            put(3);
            put(4);
            put(5);
            put(6);
            put(7);
            let l = start_limits;
            w(21, u32::from(l.peak_ma) | u32::from(l.slew_ma_per_ms) << 16);
            w(22, u32::from(l.continuous_ma));
            w(23, l.i2t_budget_ma2s);
        });
    }

    /// Publishes the fault count and the last fault (when they change, for the next
    /// `Status`).
    pub fn publish_faults(&mut self, faults: u16, last: Option<FaultRecord>) {
        write_words(self.published, |words| {
            let w = |i: usize, v: u32| words[i].store(v, Ordering::Relaxed);
            match last {
                Some(f) => {
                    w(2, u32::from(faults) | 1 << 16);
                    w(3, f.tick);
                    let kind = match f.kind {
                        Limit::Peak => 0,
                        Limit::Slew => 1,
                        Limit::Thermal => 2,
                    };
                    w(
                        4,
                        source_code(Some(f.source)) | kind << 9 | u32::from(f.channel) << 16,
                    );
                }
                None => w(2, u32::from(faults)),
            }
        });
    }
}
