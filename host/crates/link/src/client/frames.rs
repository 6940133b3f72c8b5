//! Requests on the wire and what comes back: sequence numbers, retries, replies
//! matched to their request, events queued, damaged frames counted.

use std::time::{Duration, SystemTime};

use touch_protocol::link::cobs::Feed;
use touch_protocol::link::{self, Command, Message, Reply, Request};

use super::{Client, ClientError, Stamped};
use crate::Transport;

/// How long [`Client::call_watched`] waits for its command's reply before it
/// asks with a `Status` whether the device is still there (a device restarts and
/// answers again within some 300 ms; an erase takes seconds).
const PROBE: Duration = Duration::from_millis(250);

/// Events kept for [`Client::next_event`]; older ones are dropped past this.
const MAX_QUEUED_EVENTS: usize = 4096;

impl<T: Transport> Client<T> {
    pub(super) fn chunk_len(&mut self) -> Result<usize, ClientError> {
        // Every device of this link version takes MAX_CHUNK; a smaller one says so.
        let info = self.info()?;
        Ok(usize::from(info.max_chunk).clamp(link::KEYFRAME_LEN, link::MAX_CHUNK))
    }

    /// Sends `command` and waits for its reply; `take` turns the right reply into
    /// the result (`None`: the wrong kind). Retries `retries` times when nothing
    /// came back or the device could not read the frame.
    pub(super) fn call<R>(
        &mut self,
        command: Command<'_>,
        timeout: Duration,
        retries: u32,
        mut take: impl FnMut(Reply<'_>) -> Option<R>,
    ) -> Result<R, ClientError> {
        let name = command_name(&command);
        let mut attempt = 0;
        loop {
            let seq = self.send(command)?;
            match self.await_reply(seq, name, timeout, &mut take, None) {
                Err(ClientError::Timeout { .. } | ClientError::Unreadable { .. })
                    if attempt < retries =>
                {
                    attempt += 1;
                }
                other => return other,
            }
        }
    }

    /// As [`Client::call`] without retries, for a command that keeps the device
    /// busy for a while (an erase, a commit): every [`PROBE`] without its reply, a
    /// `Status` follows it. The device answers requests in order, so a probe
    /// answered first means the device no longer knew the command: it restarted
    /// ([`ClientError::Restarted`]), found in a fraction of a second instead of
    /// at the end of `timeout`.
    pub(super) fn call_watched<R>(
        &mut self,
        command: Command<'_>,
        timeout: Duration,
        mut take: impl FnMut(Reply<'_>) -> Option<R>,
    ) -> Result<R, ClientError> {
        let name = command_name(&command);
        let seq = self.send(command)?;
        self.await_reply(seq, name, timeout, &mut take, Some(PROBE))
    }

    /// Sends one request; its sequence number.
    fn send(&mut self, command: Command<'_>) -> Result<u16, ClientError> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let mut wire = [0u8; link::MAX_ENCODED];
        let n = link::encode(&Request { seq, command }, &mut wire)
            .map_err(|_| ClientError::Protocol("a request too long to send"))?;
        self.transport.write_all(&wire[..n])?;
        Ok(seq)
    }

    /// Waits at most `timeout` for the reply to request `seq` (`command` names it in
    /// errors). With `probe`, a `Status` follows every `probe` without it, and one
    /// answered first ends the wait ([`Client::call_watched`]); without, an
    /// unreadable frame seen meanwhile is the error at the timeout (it may have been
    /// the request).
    fn await_reply<R>(
        &mut self,
        seq: u16,
        command: &'static str,
        timeout: Duration,
        take: &mut impl FnMut(Reply<'_>) -> Option<R>,
        probe: Option<Duration>,
    ) -> Result<R, ClientError> {
        let start = self.transport.now();
        let mut probes = Vec::new();
        let mut result: Option<Result<R, ClientError>> = None;
        let mut unreadable = None;
        loop {
            let until = probe.map_or(timeout, |p| (self.transport.now() - start + p).min(timeout));
            while result.is_none() && self.transport.now() - start < until {
                let left = until.saturating_sub(self.transport.now() - start);
                self.receive(left, |message| match message {
                    Message::Reply { seq: s, reply } if s == seq => {
                        result = Some(take(reply).ok_or(ClientError::UnexpectedReply { command }));
                        true
                    }
                    Message::Refused { seq: s, error } if s == seq => {
                        result = Some(Err(ClientError::Refused { command, error }));
                        true
                    }
                    Message::Reply { seq: s, .. } | Message::Refused { seq: s, .. }
                        if probes.contains(&s) =>
                    {
                        // A frame the device could not read may have been the
                        // command itself: that, rather than a restart.
                        result = Some(Err(match unreadable {
                            Some(error) => ClientError::Unreadable { command, error },
                            None => ClientError::Restarted { command },
                        }));
                        true
                    }
                    Message::Unreadable(error) => {
                        unreadable = Some(error);
                        false
                    }
                    _ => false,
                })?;
            }
            if let Some(r) = result {
                return r;
            }
            if self.transport.now() - start >= timeout {
                return Err(match (probe, unreadable) {
                    (None, Some(error)) => ClientError::Unreadable { command, error },
                    _ => ClientError::Timeout {
                        command,
                        waited: timeout,
                    },
                });
            }
            probes.push(self.send(Command::Status)?);
        }
    }

    /// Reads bytes for at most `timeout` and hands each decoded message to `seen`
    /// (events are queued instead); returns once a read brought whole messages (or
    /// `seen` returned true), or at the timeout.
    pub(super) fn receive(
        &mut self,
        timeout: Duration,
        mut seen: impl FnMut(Message<'_>) -> bool,
    ) -> Result<(), ClientError> {
        let start = self.transport.now();
        // At least one read, even with no time left: what already arrived counts.
        let mut read = false;
        loop {
            let mut decoded = false;
            while let Some(byte) = self.inbox.pop_front() {
                match self.decoder.feed(byte) {
                    Feed::Frame(frame) => match link::decode::<Message>(frame) {
                        Ok(Message::Event { tick, event }) => {
                            decoded = true;
                            // A caller that never reads events keeps the newest.
                            if self.events.len() >= MAX_QUEUED_EVENTS {
                                self.events.pop_front();
                            }
                            self.events.push_back(Stamped {
                                tick,
                                event,
                                received: SystemTime::now(),
                            });
                        }
                        Ok(message) => {
                            decoded = true;
                            if seen(message) {
                                return Ok(());
                            }
                        }
                        Err(_) => self.damaged += 1,
                    },
                    Feed::Dropped(_) => self.damaged += 1,
                    _ => {}
                }
            }
            let elapsed = self.transport.now() - start;
            if decoded || (read && elapsed >= timeout) {
                return Ok(());
            }
            let mut buf = [0u8; 512];
            let n = self
                .transport
                .read(&mut buf, timeout.saturating_sub(elapsed))?;
            read = true;
            self.inbox.extend(&buf[..n]);
            if n == 0 {
                return Ok(());
            }
        }
    }
}

/// A command's name, for messages.
fn command_name(command: &Command<'_>) -> &'static str {
    match command {
        Command::Hello { .. } => "hello",
        Command::Info => "info",
        Command::Slot { .. } => "slot",
        Command::Status => "status",
        Command::BankRead { .. } => "bank read",
        Command::BankBegin { .. } => "bank begin",
        Command::BankChunk { .. } => "bank chunk",
        Command::BankCommit => "bank commit",
        Command::BankAbort => "bank abort",
        Command::Play { .. } => "play",
        Command::Stop => "stop",
        Command::StreamBegin(_) => "stream begin",
        Command::StreamData { .. } => "stream data",
        Command::StreamEnd => "stream end",
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;
    use crate::MemoryTransport;
    use touch_protocol::link::cobs::Decoder;

    /// A scripted device: answers each request with what `answer` returns (frames
    /// to send back), until the host hangs up.
    fn device(
        mut answer: impl FnMut(u16, Command<'_>) -> Vec<Vec<u8>> + Send + 'static,
    ) -> (MemoryTransport, std::thread::JoinHandle<()>) {
        let (host, mut dev) = MemoryTransport::pair();
        let t = std::thread::spawn(move || {
            let mut decoder = Decoder::<{ link::MAX_ENCODED }>::new();
            let mut buf = [0u8; 512];
            while let Ok(n) = dev.read(&mut buf, Duration::from_secs(5)) {
                for &b in &buf[..n] {
                    if let Feed::Frame(f) = decoder.feed(b) {
                        let r: Request<'_> = link::decode(f).unwrap();
                        for frame in answer(r.seq, r.command) {
                            if dev.write_all(&frame).is_err() {
                                return;
                            }
                        }
                    }
                }
            }
        });
        (host, t)
    }

    fn frame(m: &Message<'_>) -> Vec<u8> {
        let mut wire = [0u8; link::MAX_ENCODED];
        let n = link::encode(m, &mut wire).unwrap();
        wire[..n].to_vec()
    }

    fn quick(t: MemoryTransport) -> Client<MemoryTransport> {
        Client::new(t).with_timeouts(Timeouts {
            reply: Duration::from_millis(100),
            ..Timeouts::default()
        })
    }

    #[test]
    fn a_device_that_restarted_mid_command_is_found_by_a_probe() {
        // Forgets the erase (as a restarted device does) but answers a `Status`.
        let status = StatusReport {
            tick: 1,
            playing: None,
            stopping: false,
            selected: 0,
            heat_permille: [0; 8],
            cooldown_ms: 0,
            faults: 0,
            last_fault: None,
            upload: None,
        };
        let (t, _d) = device(move |seq, c| match c {
            Command::Status => vec![frame(&Message::Reply {
                seq,
                reply: Reply::Status(status),
            })],
            _ => vec![],
        });
        let mut c = quick(t);
        let start = std::time::Instant::now();
        let r = c.call_watched(
            Command::BankBegin { len: 8, crc: 0 },
            Duration::from_secs(10),
            |_| Some(()),
        );
        assert!(
            matches!(
                r,
                Err(ClientError::Restarted {
                    command: "bank begin"
                })
            ),
            "{r:?}"
        );
        assert!(
            start.elapsed() < Duration::from_secs(2),
            "{:?}",
            start.elapsed()
        );
    }

    #[test]
    fn a_busy_device_answers_the_command_before_its_probes() {
        // An erase of 0.6 s: the probes queue behind it and are answered after it.
        let (t, _d) = device(|seq, c| match c {
            Command::BankBegin { len, .. } => {
                std::thread::sleep(Duration::from_millis(600));
                vec![frame(&Message::Reply {
                    seq,
                    reply: Reply::BankBegin { len },
                })]
            }
            _ => vec![frame(&Message::Refused {
                seq,
                error: LinkError::QueueFull,
            })],
        });
        let mut c = quick(t);
        let r = c.call_watched(
            Command::BankBegin { len: 8, crc: 0 },
            Duration::from_secs(10),
            |r| matches!(r, Reply::BankBegin { len: 8 }).then_some(()),
        );
        assert!(r.is_ok(), "{r:?}");
    }

    #[test]
    fn another_link_version_is_named_either_way() {
        let (t, _d) = device(|seq, _| {
            vec![frame(&Message::Reply {
                seq,
                reply: Reply::Hello {
                    version: link::VERSION + 1,
                    firmware: "9.9.9",
                },
            })]
        });
        match quick(t).hello() {
            Err(ClientError::Version { device, host }) => {
                assert_eq!((device, host), (link::VERSION + 1, link::VERSION))
            }
            other => panic!("{other:?}"),
        }
        let (t, _d) = device(|seq, _| {
            vec![frame(&Message::Refused {
                seq,
                error: LinkError::UnsupportedVersion { device: 7 },
            })]
        });
        assert!(matches!(
            quick(t).hello(),
            Err(ClientError::Version { device: 7, .. })
        ));
    }

    #[test]
    fn stale_replies_and_events_are_sorted_out() {
        // Before each answer: an event and a reply to an older request.
        let (t, _d) = device(|seq, _| {
            vec![
                frame(&Message::Event {
                    tick: 5,
                    event: Event::Selected(1),
                }),
                frame(&Message::Reply {
                    seq: seq.wrapping_sub(1),
                    reply: Reply::Stop(StopReply {
                        source: None,
                        tick: 1,
                    }),
                }),
                frame(&Message::Reply {
                    seq,
                    reply: Reply::Stop(StopReply {
                        source: Some(Source::Slot(2)),
                        tick: 9,
                    }),
                }),
            ]
        });
        let mut c = quick(t);
        assert_eq!(c.stop().unwrap(), (Some(Source::Slot(2)), 9));
        let e = c.next_event(Duration::ZERO).unwrap().unwrap();
        assert_eq!((e.tick, e.event), (5, Event::Selected(1)));
    }

    #[test]
    fn a_damaged_request_is_retried_when_that_is_safe_and_not_otherwise() {
        let calls = std::sync::Arc::new(std::sync::atomic::AtomicU32::new(0));
        let seen = calls.clone();
        // The first frame of all arrives damaged; the rest get through.
        let (t, _d) = device(move |seq, command| {
            if seen.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 0 {
                return vec![frame(&Message::Unreadable(FrameError::BadCrc))];
            }
            let reply = match command {
                Command::Status => return vec![],
                Command::Stop => Reply::Stop(StopReply {
                    source: None,
                    tick: 3,
                }),
                _ => Reply::Play(PlayReply {
                    slot: 0,
                    tick: 4,
                    now: true,
                }),
            };
            vec![frame(&Message::Reply { seq, reply })]
        });
        let mut c = quick(t);
        assert_eq!(c.stop().unwrap(), (None, 3), "stop is sent again");
        calls.store(0, std::sync::atomic::Ordering::SeqCst);
        match c.play(0) {
            Err(ClientError::Unreadable { command, .. }) => assert_eq!(command, "play"),
            other => panic!("a play is never sent twice: {other:?}"),
        }
        // No answer at all: a timeout that names the command.
        match c.status() {
            Err(ClientError::Timeout { command, .. }) => assert_eq!(command, "status"),
            other => panic!("{other:?}"),
        }
    }
}
