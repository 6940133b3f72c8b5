//! The host's stream in the tick: armed by `StreamBegin`, started once two
//! keyframes are in, fed a keyframe per period, stopped by its deadline, an
//! underrun, its end or a stop.

use touch_protocol::link::{self as wire, StreamStop};
use touch_protocol::{LiveParams, Player};

use super::{Controller, Playing, Report, StreamReport};
use crate::link::port::{STAGED_STREAM, STAGED_STREAM_ONE};

/// The host's stream, as the tick sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum StreamState {
    Off,
    /// Begun: waiting for its first two keyframes.
    Armed(LiveParams),
    /// Playing.
    On,
}

/// Per-stream bookkeeping: the deadline and whether the host ended it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct StreamClock {
    /// The host's data counter when last seen.
    pub(super) fed: u32,
    /// The tick it last changed, or the last tick with keyframes buffered (while
    /// the stream plays), whichever is later: what the deadline counts from.
    pub(super) fed_at: u32,
    /// The host sent `StreamEnd`: play out what is buffered, then stop.
    pub(super) ended: bool,
}

impl Controller<'_> {
    /// The stream's part of a tick: the deadline, the start once two keyframes are
    /// in, and the next keyframe for the player.
    #[inline(never)]
    pub(super) fn stream_tick(&mut self) -> Option<Report> {
        if self.stream == StreamState::Off {
            // What a stopped stream left, a few a tick: all of them at once (up to
            // 32) would cost the tick that stops it some 390 instructions. A new
            // stream drains the rest before it is armed.
            if let Some(port) = self.link.as_mut() {
                for _ in 0..4 {
                    if port.next_keyframe().is_none() {
                        break;
                    }
                }
            }
            return None;
        }
        let port = self.link.as_mut()?;
        let fed = port.fed();
        // The dead-man counts from the later of the last data and the buffer running
        // dry: a host that stalls for less than the buffer holds never cuts the
        // stimulus, and one that vanished still reaches 0 A within the deadline and
        // the ramp after the last keyframe it sent. Until the stream plays, only
        // data counts (one keyframe alone never starts it), for a longer deadline:
        // nothing plays yet.
        let buffered = self.stream == StreamState::On && port.keyframes_ready() > 0;
        if fed != self.clock.fed || buffered {
            self.clock.fed = fed;
            self.clock.fed_at = self.now;
        }
        let quiet = self.now.wrapping_sub(self.clock.fed_at);
        let deadline = match self.stream {
            StreamState::On => wire::STREAM_DEADLINE_MS,
            _ => wire::STREAM_START_MS,
        };
        if !self.clock.ended && quiet >= deadline {
            return self.stop_stream(StreamStop::Deadline);
        }
        match self.stream {
            StreamState::Armed(params) => {
                let ready = port.keyframes_ready();
                if ready < 2 && !(self.clock.ended && ready == 1) {
                    if self.clock.ended && ready == 0 {
                        self.stream = StreamState::Off;
                        return Some(Report::Stream(StreamReport::Stopping(StreamStop::Ended)));
                    }
                    return None;
                }
                if self.playing.is_some() {
                    // A slot still ramps down (it was playing at the stream's begin).
                    return None;
                }
                let limits = params.limits.min(self.device.limits);
                if let Err(hot) = self.thermal.check_start(&limits) {
                    self.stream = StreamState::Off;
                    return Some(Report::Stream(StreamReport::TooHot(hot)));
                }
                // The link's task built the player from these keyframes (both, or
                // the only one of a stream that ended after it); if not (the
                // selection moved meanwhile), the tick builds it.
                let tag = if ready >= 2 {
                    STAGED_STREAM
                } else {
                    STAGED_STREAM_ONE
                };
                if port.take_player(tag, &self.thermal) {
                    port.next_keyframe();
                    if tag == STAGED_STREAM {
                        port.next_keyframe();
                    }
                } else {
                    let first = port.next_keyframe().unwrap_or([0; 8]);
                    let second = port.next_keyframe().unwrap_or(first);
                    let player = Player::live(&params, first, second, &self.device, self.thermal);
                    port.put_player(player);
                }
                self.playing = Some(Playing::Stream);
                self.keyframes = (self.now, u32::from(params.keyframe_period_ms));
                self.stopping = false;
                self.stream = StreamState::On;
                Some(Report::Stream(StreamReport::Started))
            }
            StreamState::On => {
                if self.playing == Some(Playing::Stream) && port.player().wants_keyframe() {
                    if let Some(k) = port.next_keyframe() {
                        let _ = port.player().push_keyframe(k);
                    }
                }
                None
            }
            StreamState::Off => None,
        }
    }

    /// Ramps the stream down (or forgets an armed one) for `why`.
    pub(super) fn stop_stream(&mut self, why: StreamStop) -> Option<Report> {
        let was = self.stream;
        // Its keyframes left in the queue drain while it is off (`stream_tick`).
        self.stream = StreamState::Off;
        match self.playing {
            Some(Playing::Stream) if !self.stopping => {
                if let Some(player) = self.player_mut() {
                    player.stop();
                }
                self.stopping = true;
                Some(Report::Stream(StreamReport::Stopping(why)))
            }
            _ if matches!(was, StreamState::Armed(_)) => {
                Some(Report::Stream(StreamReport::Stopping(why)))
            }
            _ => None,
        }
    }

    pub(super) fn drain_keyframes(&mut self) {
        if let Some(port) = self.link.as_mut() {
            while port.next_keyframe().is_some() {}
        }
    }
}
