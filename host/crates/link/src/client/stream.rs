//! A stimulus streamed to the device while it plays.

use std::collections::VecDeque;
use std::time::Duration;

use touch_protocol::link::{
    self, Command, Event, LinkError, Reply, StreamBeginReply, StreamParams,
};
use touch_protocol::Stimulus;

use super::{Client, ClientError, Progress, RETRIES};
use crate::Transport;

impl<T: Transport> Client<T> {
    /// Streams a stimulus's keyframes while it plays, keeping the device's buffer
    /// filled, then ends the stream; returns once every keyframe is sent and
    /// acknowledged (the device plays out what it holds and ramps to 0 A).
    pub fn stream(
        &mut self,
        stimulus: &Stimulus<'_>,
        mut progress: impl FnMut(Progress),
    ) -> Result<(), ClientError> {
        let h = stimulus.header();
        let params = StreamParams {
            keyframe_period_ms: h.keyframe_period_ms,
            ramp_ms: h.ramp_ms,
            full_scale_ma: h.full_scale_ma,
            limits: stimulus.limits(),
        };
        let timeout = self.timeouts.reply;
        let capacity = self.call(Command::StreamBegin(params), timeout, 0, |r| match r {
            Reply::StreamBegin(StreamBeginReply { capacity }) => Some(capacity),
            _ => None,
        })?;
        let total = h.keyframe_count;
        let mut keyframes = stimulus.keyframes();
        let mut pending: VecDeque<[i16; 8]> = VecDeque::new();
        let mut next = 0u32;
        let mut room = capacity;
        // Well inside the device's deadline: the stream never starves for want of
        // a frame from the host.
        let keep_alive = Duration::from_millis(u64::from(link::STREAM_DEADLINE_MS) / 4);
        let per_chunk = link::MAX_STREAM_KEYFRAMES.min(self.chunk_len()? / link::KEYFRAME_LEN);
        loop {
            let n = (room as usize).min(per_chunk).min((total - next) as usize);
            while pending.len() < n {
                match keyframes.try_next() {
                    Ok(k) => pending.push_back(k),
                    Err(_) => return Err(ClientError::Protocol("a keyframe did not decode")),
                }
            }
            let mut payload = [0u8; link::MAX_CHUNK];
            let batch: Vec<[i16; 8]> = pending.iter().take(n).copied().collect();
            let used = link::put_stream_keyframes(&batch, &mut payload);
            let index = next;
            let acked = self.call(
                Command::StreamData {
                    index,
                    keyframes: &payload[..used],
                },
                timeout,
                0,
                |r| match r {
                    Reply::StreamData { next, room } => Some((next, room)),
                    _ => None,
                },
            );
            let (dev_next, dev_room) = match acked {
                Ok(a) => a,
                // The device ended the stream on its own (its event came first).
                Err(ClientError::Refused {
                    error: LinkError::NoStream,
                    ..
                }) => {
                    return Err(self.stream_stopped().unwrap_or(ClientError::Refused {
                        command: "stream data",
                        error: LinkError::NoStream,
                    }))
                }
                Err(e) => return Err(e),
            };
            if dev_next < next || dev_next > next + n as u32 {
                return Err(ClientError::Protocol("a stream acknowledged out of order"));
            }
            pending.drain(..(dev_next - next) as usize);
            next = dev_next;
            room = dev_room;
            progress(Progress {
                done: u64::from(next),
                total: u64::from(total),
            });
            if next >= total {
                break;
            }
            if room == 0 || n == 0 {
                self.pump(keep_alive)?;
            }
        }
        self.call(Command::StreamEnd, timeout, RETRIES, |r| match r {
            Reply::StreamEnd => Some(()),
            _ => None,
        })
    }

    /// Why the device stopped the stream, from its queued events, if it said.
    fn stream_stopped(&mut self) -> Option<ClientError> {
        // What already arrived: the event precedes the refusal on the wire.
        let _ = self.receive(std::time::Duration::ZERO, |_| false);
        self.events.iter().rev().find_map(|e| match e.event {
            Event::StreamStopped(why) => Some(ClientError::StreamStopped(why)),
            _ => None,
        })
    }
}
