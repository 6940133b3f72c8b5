//! Buttons: EXTI edges in, debounced gestures out, counted in 1 kHz ticks.
//!
//! The EXTI task posts each edge (with the level read after it) to an
//! [`EdgeMailbox`]; the 1 kHz tick takes it, debounces it ([`Debouncer`]) and turns
//! debounced levels into [`Event`]s ([`Buttons`]). Everything here is time in ticks,
//! so the host tests drive it tick by tick.

use core::sync::atomic::{AtomicU8, Ordering};

/// A level must hold this many ticks after the last edge before it counts.
pub const DEBOUNCE_TICKS: u16 = 20;

/// A press held this long is a long press (select the next slot).
pub const LONG_PRESS_TICKS: u32 = 600;

const PENDING: u8 = 1;
const PRESSED: u8 = 2;
/// Sticky: a press was posted. Read once, before the tick starts (see [`boot_events`]).
const LATCH: u8 = 4;

/// Last edge of one button, from the EXTI task to the tick interrupt, lock-free.
///
/// Only the newest edge matters: the debouncer restarts its quiet window on every
/// edge and then takes the level, so overwriting an unread edge loses nothing.
#[derive(Debug, Default)]
pub struct EdgeMailbox(AtomicU8);

impl EdgeMailbox {
    /// An empty mailbox.
    pub const fn new() -> Self {
        EdgeMailbox(AtomicU8::new(0))
    }

    /// Records an edge after which the button reads `pressed`.
    pub fn post(&self, pressed: bool) {
        let new = if pressed {
            PENDING | PRESSED | LATCH
        } else {
            PENDING
        };
        // The closure never fails: the update always happens.
        let _ = self
            .0
            .fetch_update(Ordering::Release, Ordering::Relaxed, |v| {
                Some((v & LATCH) | new)
            });
    }

    /// Takes the newest edge, if any: `Some(pressed)`.
    pub fn take(&self) -> Option<bool> {
        let v = self.0.fetch_and(LATCH, Ordering::Acquire);
        (v & PENDING != 0).then_some(v & PRESSED != 0)
    }

    /// True if a press was posted since the last call; clears the latch.
    pub fn take_latch(&self) -> bool {
        self.0.fetch_and(!LATCH, Ordering::AcqRel) & LATCH != 0
    }

    /// The newest level posted (released if none), without taking the edge.
    pub fn level(&self) -> bool {
        self.0.load(Ordering::Acquire) & PRESSED != 0
    }
}

/// Debounces one button: a level counts once no edge came for [`DEBOUNCE_TICKS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Debouncer {
    stable: bool,
    raw: bool,
    quiet: u16,
}

impl Default for Debouncer {
    fn default() -> Self {
        Self::new()
    }
}

impl Debouncer {
    /// Starts released: a button already held at power-up reads as a press once its
    /// level is posted, so the first press is never lost.
    pub const fn new() -> Self {
        Debouncer {
            stable: false,
            raw: false,
            quiet: 0,
        }
    }

    /// The debounced level.
    pub fn pressed(&self) -> bool {
        self.stable
    }

    /// One tick; `edge` is the newest edge since the last tick. Returns the new
    /// debounced level when it changes.
    pub fn tick(&mut self, edge: Option<bool>) -> Option<bool> {
        if let Some(level) = edge {
            self.raw = level;
            self.quiet = DEBOUNCE_TICKS;
        }
        if self.quiet == 0 {
            return None;
        }
        self.quiet -= 1;
        if self.quiet == 0 && self.raw != self.stable {
            self.stable = self.raw;
            return Some(self.stable);
        }
        None
    }
}

/// What the buttons ask of the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "hw"), derive(defmt::Format))]
pub enum Event {
    /// Play the selected slot, or stop (ramping down) if it plays.
    Toggle,
    /// Stop anything playing and select the next slot.
    Next,
    /// Play this slot (stop it if it is the one playing).
    Slot(usize),
}

/// How buttons map to events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// One button: a short press plays or stops (on release), a long press selects
    /// the next slot (as soon as it is long).
    PlayNext,
    /// Button `i` plays or stops slot `i`, on the press.
    PerSlot,
}

/// `N` debounced buttons and their gesture timing.
#[derive(Debug, Clone)]
pub struct Buttons<const N: usize> {
    mode: Mode,
    debounce: [Debouncer; N],
    /// Ticks the button has been held, while held.
    held: [Option<u32>; N],
}

impl<const N: usize> Buttons<N> {
    /// All buttons released.
    pub const fn new(mode: Mode) -> Self {
        Buttons {
            mode,
            debounce: [Debouncer::new(); N],
            held: [None; N],
        }
    }

    /// One tick with the newest edge of each button; returns the events, at most
    /// one per button.
    pub fn tick(&mut self, edges: [Option<bool>; N]) -> heapless::Vec<Event, N> {
        let mut events = heapless::Vec::new();
        for (i, edge) in edges.into_iter().enumerate() {
            let change = self.debounce[i].tick(edge);
            if let Some(event) = self.gesture(i, change) {
                // Capacity is N and each button adds at most one event.
                let _ = events.push(event);
            }
        }
        events
    }

    fn gesture(&mut self, i: usize, change: Option<bool>) -> Option<Event> {
        match (self.mode, change) {
            (Mode::PerSlot, Some(true)) => Some(Event::Slot(i)),
            (Mode::PerSlot, _) => None,
            (Mode::PlayNext, Some(true)) => {
                self.held[i] = Some(0);
                None
            }
            (Mode::PlayNext, Some(false)) => match self.held[i].take() {
                Some(t) if t < LONG_PRESS_TICKS => Some(Event::Toggle),
                _ => None,
            },
            (Mode::PlayNext, None) => {
                let t = self.held[i].as_mut()?;
                *t = t.saturating_add(1);
                (*t == LONG_PRESS_TICKS).then_some(Event::Next)
            }
        }
    }
}

/// Presses that began and ended while the firmware booted, before the tick ran:
/// each becomes its event now, so the first press after power-up is never lost.
/// (A press still held is not one of them: the tick sees its level and handles it.)
/// Call once, just before the tick starts.
pub fn boot_events<const N: usize>(
    mode: Mode,
    mailboxes: &[EdgeMailbox; N],
) -> heapless::Vec<Event, N> {
    let mut events = heapless::Vec::new();
    for (i, mailbox) in mailboxes.iter().enumerate() {
        if mailbox.take_latch() && !mailbox.level() {
            let event = match mode {
                Mode::PlayNext => Event::Toggle,
                Mode::PerSlot => Event::Slot(i),
            };
            // Capacity is N and each button adds at most one event.
            let _ = events.push(event);
        }
    }
    events
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn run(
        buttons: &mut Buttons<1>,
        edge: Option<bool>,
        ticks: u32,
    ) -> std::vec::Vec<(u32, Event)> {
        let mut out = std::vec::Vec::new();
        for t in 0..ticks {
            let e = if t == 0 { edge } else { None };
            for ev in buttons.tick([e]) {
                out.push((t, ev));
            }
        }
        out
    }

    #[test]
    fn mailbox_keeps_newest_edge_once() {
        let m = EdgeMailbox::new();
        assert_eq!(m.take(), None);
        m.post(true);
        m.post(false);
        assert_eq!(m.take(), Some(false));
        assert_eq!(m.take(), None);
    }

    #[test]
    fn a_press_during_boot_is_kept() {
        let boxes = [EdgeMailbox::new(), EdgeMailbox::new(), EdgeMailbox::new()];
        boxes[0].post(false); // initial level, never pressed
        boxes[1].post(true); // pressed and released during boot
        boxes[1].post(false);
        boxes[2].post(true); // still held: the tick handles it
        assert_eq!(boot_events(Mode::PerSlot, &boxes), [Event::Slot(1)]);
        assert_eq!(boxes[2].take(), Some(true));
        // Read once: the latch is cleared, the edges stay for the tick.
        assert!(boot_events(Mode::PlayNext, &boxes).is_empty());
        assert_eq!(boxes[1].take(), Some(false));
    }

    #[test]
    fn bounces_collapse_into_one_change() {
        let mut d = Debouncer::new();
        let edges = [
            Some(true),
            Some(false),
            None,
            Some(true),
            None,
            Some(false),
            Some(true),
        ];
        for e in edges {
            assert_eq!(d.tick(e), None);
        }
        let mut changes = 0;
        for t in 0..DEBOUNCE_TICKS {
            if let Some(level) = d.tick(None) {
                assert!(level);
                assert_eq!(t, DEBOUNCE_TICKS - 2);
                changes += 1;
            }
        }
        assert_eq!(changes, 1);
        assert!(d.pressed());
    }

    #[test]
    fn short_press_toggles_on_release_long_press_selects_next() {
        let mut b = Buttons::<1>::new(Mode::PlayNext);
        assert!(run(&mut b, Some(true), 100).is_empty());
        let ev = run(&mut b, Some(false), 100);
        assert_eq!(ev, [(DEBOUNCE_TICKS as u32 - 1, Event::Toggle)]);

        assert!(run(&mut b, Some(true), 50).is_empty());
        let ev = run(&mut b, None, LONG_PRESS_TICKS + 50);
        assert_eq!(ev.len(), 1);
        assert_eq!(ev[0].1, Event::Next);
        // Releasing a long press does nothing more.
        assert!(run(&mut b, Some(false), 100).is_empty());
    }

    #[test]
    fn first_press_after_power_up_counts() {
        // Held at power-up: the EXTI task posts the level it reads at start.
        let mut b = Buttons::<1>::new(Mode::PlayNext);
        run(&mut b, Some(true), 30);
        assert_eq!(run(&mut b, Some(false), 30).len(), 1);
    }

    #[test]
    fn per_slot_plays_on_press() {
        let mut b = Buttons::<3>::new(Mode::PerSlot);
        let mut seen = std::vec::Vec::new();
        for t in 0..40u16 {
            let edges = if t == 0 {
                [None, None, Some(true)]
            } else {
                [None; 3]
            };
            for ev in b.tick(edges) {
                seen.push((t, ev));
            }
        }
        assert_eq!(seen, [(DEBOUNCE_TICKS - 1, Event::Slot(2))]);
    }

    proptest! {
        /// Whatever the bounce pattern, the debounced level follows the last edge
        /// once quiet, and never changes twice within the debounce window.
        #[test]
        fn debounced_level_is_last_edge(edges in proptest::collection::vec(proptest::option::of(any::<bool>()), 0..200)) {
            let mut d = Debouncer::new();
            let mut last_change: Option<usize> = None;
            let mut last_level = false;
            for (t, e) in edges.iter().enumerate() {
                if let Some(l) = e { last_level = *l; }
                if d.tick(*e).is_some() {
                    if let Some(p) = last_change { prop_assert!(t - p >= usize::from(DEBOUNCE_TICKS)); }
                    last_change = Some(t);
                }
            }
            for _ in 0..DEBOUNCE_TICKS { d.tick(None); }
            prop_assert_eq!(d.pressed(), last_level);
        }
    }
}
