//! What the host and the log hear: reports turned into link events, and what the
//! tick that starts a slot leaves to the next tick to send.

use touch_protocol::link::{self as wire, PlayReply, Source, TickReply};
use touch_protocol::thermal::TooHot;

use super::{Controller, Report, StreamReport};
use crate::button::Event;
use crate::link::Answer;

/// What the tick that starts a slot leaves to the next tick to tell the host (it
/// has no room left for it): the same messages, with the same ticks, a
/// millisecond later.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct Later {
    /// A `Play` that started its slot: its sequence number, the slot and the tick
    /// of the first frame.
    pub(super) play: Option<(u16, u8, u32)>,
    /// A button gesture and its tick.
    pub(super) gesture: Option<(wire::Gesture, u32)>,
    /// A report, the tick of the frames it describes, and whether the log has it
    /// yet.
    pub(super) report: Option<(Report, u32, bool)>,
}

impl Later {
    pub(super) fn is_empty(&self) -> bool {
        self.play.is_none() && self.gesture.is_none() && self.report.is_none()
    }
}

impl Controller<'_> {
    /// Sends what the last tick left for this one (`Later`), before anything
    /// else this tick tells the host (the engine calls it before the buttons'). The
    /// tick that does takes no link command.
    #[inline(always)]
    pub fn send_later(&mut self, log: &mut impl FnMut(Report)) {
        if !self.later.is_empty() {
            self.send_later_now(log);
        }
    }

    #[inline(never)]
    fn send_later_now(&mut self, log: &mut dyn FnMut(Report)) {
        let later = core::mem::take(&mut self.later);
        if let Some((seq, slot, tick)) = later.play {
            let reply = TickReply::Play(PlayReply {
                slot,
                tick,
                now: true,
            });
            self.send(Answer::Reply(seq, reply));
        }
        if let Some((gesture, tick)) = later.gesture {
            self.send(Answer::Event(tick, wire::Event::Button(gesture)));
        }
        if let Some((r, tick, logged)) = later.report {
            self.announce_at(r, tick);
            if !logged {
                log(r);
            }
        }
        self.sent_later = true;
    }

    /// Tells the host and the log what a report of this tick says.
    pub(super) fn emit(&mut self, report: Report, log: &mut (impl FnMut(Report) + ?Sized)) {
        self.announce(report);
        log(report);
    }

    /// Tells the host what a report says (the frames it describes go out at the next
    /// tick).
    pub(super) fn announce(&mut self, report: Report) {
        self.announce_at(report, self.now.wrapping_add(1));
    }

    /// Tells the host what a report says, with the tick of the frames it describes.
    #[inline(never)]
    fn announce_at(&mut self, report: Report, tick: u32) {
        if self.link.is_none() {
            return;
        }
        let slot = |s: usize| Source::Slot(s as u8);
        let event = match report {
            Report::Started(s) => wire::Event::Started(slot(s)),
            Report::Stopping(s) => wire::Event::Stopping(slot(s)),
            Report::Finished(s) => wire::Event::Finished(slot(s)),
            Report::Fault(s, f) => wire::Event::LimitHit {
                source: slot(s),
                kind: f.kind.into(),
                channel: f.channel,
            },
            Report::Selected(s) => wire::Event::Selected(s as u8),
            Report::BadSlot(s, _) => wire::Event::BadSlot(s as u8),
            Report::TooHot(s, hot) => too_hot(slot(s), hot),
            Report::Stream(StreamReport::Started) => wire::Event::Started(Source::Stream),
            Report::Stream(StreamReport::Stopping(why)) => wire::Event::StreamStopped(why),
            Report::Stream(StreamReport::Finished) => wire::Event::Finished(Source::Stream),
            Report::Stream(StreamReport::Fault(f)) => wire::Event::LimitHit {
                source: Source::Stream,
                kind: f.kind.into(),
                channel: f.channel,
            },
            Report::Stream(StreamReport::TooHot(hot)) => too_hot(Source::Stream, hot),
        };
        self.send(Answer::Event(tick, event));
    }

    /// Queues an answer for the link (dropped if its queue is full: the link drains
    /// it every millisecond or so).
    pub(super) fn send(&mut self, answer: Answer) {
        if let Some(port) = self.link.as_mut() {
            port.send(answer);
        }
    }
}

fn too_hot(source: Source, hot: TooHot) -> wire::Event {
    wire::Event::TooHot {
        source,
        channel: hot.channel,
        permille: hot.permille,
        cooldown_ms: hot.cooldown_ms,
    }
}

pub(super) fn gesture(event: Event) -> wire::Gesture {
    match event {
        Event::Toggle => wire::Gesture::Toggle,
        Event::Next => wire::Gesture::Next,
        Event::Slot(s) => wire::Gesture::Slot(s as u8),
    }
}
