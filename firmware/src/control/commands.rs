//! The link's commands in the tick: at most one a tick, answered at once or by
//! the next tick.

use touch_protocol::link::{
    self as wire, LinkError, PlayReply, StopReply, StreamBeginReply, StreamStop, TickReply,
};
use touch_protocol::Error;

use super::stream::{StreamClock, StreamState};
use super::{source, Controller, Report};
use crate::link::port::ANSWER_MARGIN;
use crate::link::{Answer, Control};

impl Controller<'_> {
    /// Takes at most one link command per tick and answers it; what it did goes to
    /// `log` (and to the host) as it happens, as the tick's own reports do.
    #[inline(never)]
    pub(super) fn serve_link(&mut self, log: &mut dyn FnMut(Report)) {
        // Left in the queue until it is done with: a `Play` may wait for its player.
        // Not while the link is behind with the answers: the reply would be dropped.
        let Some(&control) = self
            .link
            .as_ref()
            .filter(|p| p.answer_room() >= ANSWER_MARGIN)
            .and_then(|p| p.peek_control())
        else {
            return;
        };
        let first = self.now.wrapping_add(1);
        match control {
            Control::Play { seq, slot } => {
                if !self.link_play(seq, usize::from(slot), log) {
                    return;
                }
            }
            Control::Stop { seq } => {
                self.queued = None;
                let source = self.playing.map(source);
                let report = match self.stream {
                    StreamState::Armed(_) => self.stop_stream(StreamStop::Ended),
                    _ => self.stop(),
                };
                let reply = TickReply::Stop(StopReply {
                    source,
                    tick: if source.is_some() { first } else { self.now },
                });
                self.send(Answer::Reply(seq, reply));
                if let Some(r) = report {
                    self.emit(r, log);
                }
            }
            // A player that takes its next keyframe decodes it in that tick: the
            // snapshot waits a tick rather than add to it.
            Control::Status { .. } if self.keyframe_tick() => return,
            Control::Status { seq } => {
                self.publish();
                self.send(Answer::Status(seq));
            }
            Control::StreamBegin { seq, params } => {
                if let Some(e) = self.refuse_start() {
                    self.send(Answer::Refused(seq, e));
                } else {
                    self.drain_keyframes();
                    self.stream = StreamState::Armed(params);
                    let fed = self.link.as_ref().map_or(0, |p| p.fed());
                    self.clock = StreamClock {
                        fed,
                        fed_at: self.now,
                        ended: false,
                    };
                    let capacity = self.link.as_ref().map_or(0, |p| p.keyframe_capacity());
                    self.send(Answer::Reply(
                        seq,
                        TickReply::StreamBegin(StreamBeginReply { capacity }),
                    ));
                }
            }
            Control::StreamEnd { seq } => {
                if self.stream == StreamState::Off {
                    self.send(Answer::Refused(seq, LinkError::NoStream));
                } else {
                    self.clock.ended = true;
                    self.send(Answer::Reply(seq, TickReply::StreamEnd));
                }
            }
            Control::Lock { seq } => {
                if self.playing.is_some() || self.stream != StreamState::Off {
                    self.send(Answer::Refused(seq, LinkError::Busy(wire::Busy::Playing)));
                } else {
                    self.locked = true;
                    self.queued = None;
                    self.send(Answer::Locked(seq));
                }
            }
        }
        if let Some(port) = &mut self.link {
            port.next_control();
        }
    }

    /// True if this tick's player takes its next keyframe (a player's `k`-th tick
    /// from its start does when `k + 1` is a multiple of the period), while it plays
    /// its keyframes. Never with a period under 2 ms, where every tick does.
    fn keyframe_tick(&self) -> bool {
        let (start, period) = self.keyframes;
        self.playing.is_some()
            && !self.stopping
            && period >= 2
            && self.now.wrapping_sub(start) % period == period - 1
    }

    /// Why nothing may start now, if so: an upload owns the bank, a stream is on.
    fn refuse_start(&self) -> Option<LinkError> {
        if self.locked {
            Some(LinkError::Busy(wire::Busy::Uploading))
        } else if self.stream != StreamState::Off || self.streaming() {
            Some(LinkError::Busy(wire::Busy::Streaming))
        } else if self.playing.is_some() {
            Some(LinkError::Busy(wire::Busy::Playing))
        } else {
            None
        }
    }

    /// A `Play`: answers it (and hands on what it did), or returns false while it
    /// waits for its player (it stays in the queue, the link's task builds it).
    fn link_play(&mut self, seq: u16, slot: usize, log: &mut dyn FnMut(Report)) -> bool {
        let slots = self.slots() as u8;
        let first = self.now.wrapping_add(1);
        let limits = match self.start_limits(slot) {
            _ if self.locked => Err(LinkError::Busy(wire::Busy::Uploading)),
            _ if self.stream != StreamState::Off || self.streaming() => {
                Err(LinkError::Busy(wire::Busy::Streaming))
            }
            Err(Error::NoSuchSlot(_)) => Err(LinkError::NoSuchSlot {
                slot: slot.min(255) as u8,
                slots,
            }),
            Err(_) => Err(LinkError::BadSlot { slot: slot as u8 }),
            Ok(limits) => Ok(limits),
        };
        let limits = match limits {
            Ok(limits) => limits,
            Err(e) => {
                self.send(Answer::Refused(seq, e));
                return true;
            }
        };
        let wire_slot = slot as u8;
        if self.playing.is_some() {
            // As a press on another slot: the one playing ramps down first.
            let report = self.stop();
            self.queue(slot);
            let reply = TickReply::Play(PlayReply {
                slot: wire_slot,
                tick: first,
                now: false,
            });
            self.send(Answer::Reply(seq, reply));
            if let Some(r) = report {
                self.emit(r, log);
            }
            return true;
        }
        // A press's start still waiting for its player gives way to the host's.
        self.queued = None;
        let Some(port) = self.link.as_mut() else {
            return true;
        };
        if !port.staged(wire_slot) {
            // The server stages the player before it forwards the `Play`; a press
            // took it or asked for another meanwhile.
            port.want(wire_slot);
            return false;
        }
        let selected = self.selected;
        self.selected = slot;
        // The thermal check is the start's own, as for a press.
        match self.start_with(slot, &limits) {
            Some(Report::TooHot(_, hot)) => {
                self.selected = selected;
                let e = LinkError::TooHot {
                    channel: hot.channel,
                    permille: hot.permille,
                    cooldown_ms: hot.cooldown_ms,
                };
                self.send(Answer::Refused(seq, e));
            }
            report => {
                // Its first frame goes out in this tick, once computed (`tick_with`):
                // the player's steps then run one tick ahead of the clock.
                let first = if self.playing.is_some() {
                    self.ahead = true;
                    self.keyframes.0 = self.now.wrapping_sub(1);
                    self.now
                } else {
                    first
                };
                // Answered by the next tick (`send_later`).
                self.later.play = Some((seq, wire_slot, first));
                match report {
                    Some(r) if self.later.report.is_none() => {
                        self.later.report = Some((r, first, false));
                    }
                    Some(r) => self.emit(r, log),
                    None => {}
                }
            }
        }
        true
    }

    /// Publishes the state the link's `Status` reports (the per-mille arithmetic is
    /// the link server's, outside the tick; the faults were published as they came).
    fn publish(&mut self) {
        let (tick, playing, stopping) = (self.now, self.playing.map(source), self.stopping);
        let selected = self.selected as u8;
        let limits = &self.limits[self.selected % self.limits.len()];
        if let Some(port) = &mut self.link {
            // While something plays its player holds the heat (in the port).
            let idle = playing.is_none().then_some(&self.thermal);
            port.publish_status(tick, playing, stopping, selected, limits, idle);
        }
    }
}
