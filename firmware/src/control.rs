//! Which slot plays: button events in, one player stepped per tick.
//!
//! Safety rules kept here: a new stimulus never starts on top of another (the
//! running one ramps down first, the new one is queued), a stop always ramps, and
//! with nothing playing the frame is [`IDLE_FRAME`].
//!
//! Every slot is decoded once, at boot: decoding checks a stimulus's CRC and every
//! keyframe, far too slow for the tick, so starting one in the tick is only
//! [`Player::new`].

use touch_protocol::bank::MAX_SLOTS;
use touch_protocol::player::{Fault, Status};
use touch_protocol::{Bank, DeviceConfig, Player, Stimulus};

use crate::button::Event;
use crate::output::{Frame, IDLE_FRAME};

/// What happened, for the log (the tick interrupt never logs itself).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "hw"), derive(defmt::Format))]
pub enum Report {
    /// Slot started playing.
    Started(usize),
    /// A stop was requested; the outputs ramp down.
    Stopping(usize),
    /// The slot finished; all outputs are at 0 A.
    Finished(usize),
    /// A limit was hit in the slot; the outputs ramp down.
    Fault(usize, Fault),
    /// The selection moved to this slot.
    Selected(usize),
    /// The slot could not be read from the bank (never after a good boot check).
    BadSlot(usize),
}

/// The playback state machine, stepped once per 1 kHz tick.
#[derive(Debug)]
pub struct Controller<'a> {
    /// The bank's slots, decoded (`None`: the slot did not decode).
    stimuli: heapless::Vec<Option<Stimulus<'a>>, { MAX_SLOTS as usize }>,
    device: DeviceConfig,
    selected: usize,
    /// The slot playing (or ramping down) and its player.
    playing: Option<(usize, Player<'a>)>,
    /// True once the playing slot was asked to stop or ended: it ramps down.
    stopping: bool,
    /// Slot to start as soon as the current one reached 0 A.
    queued: Option<usize>,
}

impl<'a> Controller<'a> {
    /// Nothing playing, slot 0 selected. Decodes every slot (slow: call at boot).
    pub fn new(bank: Bank<'a>, device: DeviceConfig) -> Self {
        let stimuli = (0..bank.len().min(MAX_SLOTS as usize))
            .map(|slot| bank.slot(slot).ok())
            .collect();
        Controller {
            stimuli,
            device,
            selected: 0,
            playing: None,
            stopping: false,
            queued: None,
        }
    }

    /// Number of slots.
    pub fn slots(&self) -> usize {
        self.stimuli.len()
    }

    /// The selected slot (what a short press plays).
    pub fn selected(&self) -> usize {
        self.selected
    }

    /// The slot playing or ramping down, if any.
    pub fn playing(&self) -> Option<usize> {
        self.playing.as_ref().map(|(slot, _)| *slot)
    }

    /// Applies one button event; returns what to log.
    pub fn handle(&mut self, event: Event) -> Option<Report> {
        match event {
            Event::Toggle => self.toggle(self.selected),
            Event::Slot(slot) if slot < self.slots() => {
                self.selected = slot;
                self.toggle(slot)
            }
            Event::Slot(_) => None,
            Event::Next => {
                self.queued = None;
                self.stop();
                self.selected = (self.selected + 1) % self.slots().max(1);
                Some(Report::Selected(self.selected))
            }
        }
    }

    /// Press on `slot`: stop it if it plays, else play it (after the current one
    /// ramped down, if another plays).
    fn toggle(&mut self, slot: usize) -> Option<Report> {
        match self.playing {
            Some((current, _)) if current == slot && !self.stopping => {
                self.queued = None;
                self.stop()
            }
            Some(_) => {
                self.stop();
                self.queued = Some(slot);
                None
            }
            None => self.start(slot),
        }
    }

    fn stop(&mut self) -> Option<Report> {
        let (slot, player) = self.playing.as_mut()?;
        if self.stopping {
            return None;
        }
        player.stop();
        self.stopping = true;
        Some(Report::Stopping(*slot))
    }

    fn start(&mut self, slot: usize) -> Option<Report> {
        match self.stimuli.get(slot).copied().flatten() {
            Some(stimulus) => {
                self.playing = Some((slot, Player::new(&stimulus, &self.device)));
                self.stopping = false;
                Some(Report::Started(slot))
            }
            None => Some(Report::BadSlot(slot)),
        }
    }

    /// Computes the next frame; returns it and what to log.
    pub fn next_frame(&mut self) -> (Frame, Option<Report>) {
        if self.playing.is_none() {
            if let Some(slot) = self.queued.take() {
                let report = self.start(slot);
                if self.playing.is_none() {
                    return (IDLE_FRAME, report);
                }
            }
        }
        let Some((slot, player)) = self.playing.as_mut() else {
            return (IDLE_FRAME, None);
        };
        let slot = *slot;
        let tick = player.tick();
        let report = match tick.status {
            Status::Playing => None,
            Status::RampingDown => {
                self.stopping = true;
                None
            }
            Status::Fault(fault) => {
                self.stopping = true;
                Some(Report::Fault(slot, fault))
            }
            Status::Finished => {
                self.playing = None;
                self.stopping = false;
                Some(Report::Finished(slot))
            }
        };
        (tick.codes, report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::device_config;
    use crate::testutil::{bank, constant_stimulus};
    use touch_protocol::IDLE_CODE;

    fn run(c: &mut Controller<'_>, ticks: usize) -> std::vec::Vec<Frame> {
        (0..ticks).map(|_| c.next_frame().0).collect()
    }

    #[test]
    fn idle_until_a_press_then_plays_and_ends_at_zero() {
        let image = bank(&[constant_stimulus("a", 300, 100)]);
        let b = Bank::decode(&image).unwrap();
        let mut c = Controller::new(b, device_config());
        assert!(run(&mut c, 50).iter().all(|f| *f == IDLE_FRAME));
        assert_eq!(c.handle(Event::Toggle), Some(Report::Started(0)));
        let frames = run(&mut c, 2000);
        assert_ne!(frames[0], IDLE_FRAME);
        assert_eq!(*frames.last().unwrap(), IDLE_FRAME);
        assert_eq!(c.playing(), None);
    }

    #[test]
    fn stop_ramps_down_and_press_during_ramp_queues_a_restart() {
        let image = bank(&[constant_stimulus("a", 300, 5000)]);
        let b = Bank::decode(&image).unwrap();
        let mut c = Controller::new(b, device_config());
        c.handle(Event::Toggle);
        let playing = run(&mut c, 200);
        assert_eq!(c.handle(Event::Toggle), Some(Report::Stopping(0)));
        // Ramping down: no step, still moving toward idle.
        let last = playing.last().unwrap()[0];
        let next = c.next_frame().0[0];
        assert!(next.abs_diff(IDLE_CODE) <= last.abs_diff(IDLE_CODE));
        // Press again while ramping: queued, starts once at 0 A.
        assert_eq!(c.handle(Event::Toggle), None);
        let frames = run(&mut c, 500);
        assert!(frames.contains(&IDLE_FRAME));
        assert_eq!(c.playing(), Some(0));
    }

    #[test]
    fn next_stops_and_wraps_selection() {
        let image = bank(&[
            constant_stimulus("a", 300, 5000),
            constant_stimulus("b", -300, 5000),
        ]);
        let b = Bank::decode(&image).unwrap();
        let mut c = Controller::new(b, device_config());
        c.handle(Event::Toggle);
        run(&mut c, 100);
        assert_eq!(c.handle(Event::Next), Some(Report::Selected(1)));
        assert_eq!(c.handle(Event::Next), Some(Report::Selected(0)));
        let frames = run(&mut c, 500);
        assert_eq!(*frames.last().unwrap(), IDLE_FRAME);
        // A slot past the bank is ignored.
        assert_eq!(c.handle(Event::Slot(7)), None);
    }

    #[test]
    fn switching_slots_never_steps() {
        let image = bank(&[
            constant_stimulus("a", 900, 5000),
            constant_stimulus("b", -900, 5000),
        ]);
        let b = Bank::decode(&image).unwrap();
        let mut c = Controller::new(b, device_config());
        c.handle(Event::Slot(0));
        let mut prev = IDLE_FRAME;
        for t in 0..3000 {
            if t == 400 {
                c.handle(Event::Slot(1));
            }
            let f = c.next_frame().0;
            for ch in 0..f.len() {
                // 50 mA/ms at 1000 mA full scale: at most ~103 codes per tick.
                assert!(
                    f[ch].abs_diff(prev[ch]) <= 104,
                    "tick {t} ch {ch}: {} -> {}",
                    prev[ch],
                    f[ch]
                );
            }
            prev = f;
        }
        assert_eq!(c.playing(), Some(1));
    }
}
