//! The host's end of the link: requests with sequence numbers, replies matched to
//! them, events queued, timeouts, and the multi-frame operations (upload, stream).

use std::collections::VecDeque;
use std::time::{Duration, SystemTime};

use touch_protocol::link::cobs::{Decoder, Feed};
use touch_protocol::link::{
    self, BankState, Command, Event, FrameError, LinkError, Message, Reply, Request, Source,
    StatusReport, StreamParams,
};
use touch_protocol::{Limits, Stimulus};

use super::Transport;

/// How long the client waits for each kind of reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timeouts {
    /// Any reply that needs no flash work.
    pub reply: Duration,
    /// The reply to `BankBegin`: the device erases the bank region first (two
    /// 128 KB sectors, up to 2 s each by the datasheet).
    pub erase: Duration,
    /// A device that restarts (after a commit) to answer again.
    pub restart: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Timeouts {
            reply: Duration::from_millis(500),
            erase: Duration::from_secs(10),
            restart: Duration::from_secs(5),
        }
    }
}

/// Why a link operation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClientError {
    /// The byte stream failed (the port vanished, the device was unplugged).
    #[error("the link failed: {0}")]
    Io(#[from] std::io::Error),
    /// No answer in time.
    #[error("no reply to {command} within {} ms", waited.as_millis())]
    Timeout {
        /// The command's name.
        command: &'static str,
        /// How long the client waited.
        waited: Duration,
    },
    /// The device could not read the request (damaged on the way) and no retry
    /// got through.
    #[error("the device could not read {command}: {error}")]
    Unreadable {
        /// The command's name.
        command: &'static str,
        /// What the device found wrong with the frame.
        error: FrameError,
    },
    /// The device refused the command; nothing changed on it.
    #[error("the device refused {command}: {error:?}")]
    Refused {
        /// The command's name.
        command: &'static str,
        /// Why.
        error: LinkError,
    },
    /// The device answered with a reply of another kind.
    #[error("the device answered {command} with another reply")]
    UnexpectedReply {
        /// The command's name.
        command: &'static str,
    },
    /// The device speaks another version of the link.
    #[error("the device speaks link version {device}, this host {host}")]
    Version {
        /// The device's version.
        device: u16,
        /// This host's ([`link::VERSION`]).
        host: u16,
    },
    /// The bank the device holds after an upload is not the image sent.
    #[error("the sleeve's bank differs from the image sent: {0}")]
    Verify(VerifyError),
    /// A device bug: a reply that breaks the protocol (a chunk acknowledged at
    /// another offset, a stream index going back).
    #[error("the device broke the protocol: {0}")]
    Protocol(&'static str),
}

/// How a bank read back differs from the image sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum VerifyError {
    /// The device does not play a bank from its region.
    #[error("it plays no bank from its region")]
    NotFlashed,
    /// Its bank has another length.
    #[error("{got} bytes, {expected} sent")]
    Length {
        /// Bytes sent.
        expected: u32,
        /// Bytes the device reports.
        got: u32,
    },
    /// The commit's reply carries another CRC than the image's.
    #[error("commit CRC {got:#010x}, the image's {expected:#010x}")]
    CommitCrc {
        /// The image's CRC-32.
        expected: u32,
        /// The reply's.
        got: u32,
    },
    /// A byte read back differs.
    #[error("byte {0} differs")]
    Byte(usize),
}

/// What a sleeve says about itself ([`link::Info`], owned).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceInfo {
    /// The link version.
    pub link_version: u16,
    /// The firmware's version.
    pub firmware: String,
    /// The actuator layout the firmware drives.
    pub layout: String,
    /// The layout's geometry hash.
    pub layout_hash: u32,
    /// Current at the outputs' full scale, mA.
    pub full_scale_ma: u16,
    /// The device's hard limits.
    pub limits: Limits,
    /// Largest postcard message the device takes.
    pub max_message: u16,
    /// Largest chunk payload.
    pub max_chunk: u16,
    /// Bytes of the bank region.
    pub bank_capacity: u32,
    /// The bank it plays.
    pub bank: BankState,
}

/// One slot of the sleeve's bank ([`link::SlotInfo`], owned).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlotEntry {
    /// Its index.
    pub slot: u8,
    /// The stimulus's name.
    pub name: String,
    /// The keyframed signal's length, ms.
    pub duration_ms: u32,
    /// Playback with the final ramp, ms.
    pub playback_ms: u32,
    /// False if the firmware refuses it.
    pub playable: bool,
}

/// An event as the host received it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamped {
    /// The device's 1 kHz tick.
    pub tick: u32,
    /// What happened.
    pub event: Event,
    /// The host's clock when the frame arrived.
    pub received: SystemTime,
}

/// How far an upload or a stream got: `done` of `total` bytes or keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Sent and acknowledged.
    pub done: u64,
    /// In all.
    pub total: u64,
}

/// The answer to `Play` ([`Reply::Play`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Started {
    /// The tick of the first frame, or of the ramp down before it (`now` false).
    pub tick: u32,
    /// True if the slot started at `tick`.
    pub now: bool,
}

/// A link to one sleeve over any [`Transport`].
pub struct Client<T: Transport> {
    transport: T,
    seq: u16,
    decoder: Box<Decoder<{ link::MAX_ENCODED }>>,
    /// Bytes read but not yet fed to the decoder.
    inbox: VecDeque<u8>,
    events: VecDeque<Stamped>,
    timeouts: Timeouts,
    /// Frames from the device that did not decode (damage on the way in).
    damaged: u64,
}

/// Events kept for [`Client::next_event`]; older ones are dropped past this.
const MAX_QUEUED_EVENTS: usize = 4096;

/// How long a restarting device is left alone before [`Client::reconnect`] asks.
const RESTART_GRACE: Duration = Duration::from_millis(100);

/// Retries of a command that is safe to send twice.
const RETRIES: u32 = 2;

impl<T: Transport> Client<T> {
    /// A client on `transport` with the default timeouts. Nothing is sent yet.
    pub fn new(transport: T) -> Self {
        Client {
            transport,
            seq: 0,
            decoder: Box::new(Decoder::new()),
            inbox: VecDeque::new(),
            events: VecDeque::new(),
            timeouts: Timeouts::default(),
            damaged: 0,
        }
    }

    /// Sets the timeouts.
    #[cfg(test)]
    pub(crate) fn with_timeouts(mut self, timeouts: Timeouts) -> Self {
        self.timeouts = timeouts;
        self
    }

    /// The transport, for a test that drives the other end.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// Frames from the device that did not decode so far.
    pub fn damaged_frames(&self) -> u64 {
        self.damaged
    }

    /// Opens the session: checks that the device speaks this link version and
    /// returns its firmware version.
    pub fn hello(&mut self) -> Result<String, ClientError> {
        let timeout = self.timeouts.reply;
        let r = self.call(
            Command::Hello {
                version: link::VERSION,
            },
            timeout,
            RETRIES,
            |r| match r {
                Reply::Hello { version, firmware } => Some((version, firmware.to_owned())),
                _ => None,
            },
        );
        match r {
            Ok((device, _)) if device != link::VERSION => Err(ClientError::Version {
                device,
                host: link::VERSION,
            }),
            Ok((_, firmware)) => Ok(firmware),
            Err(ClientError::Refused {
                error: LinkError::UnsupportedVersion { device },
                ..
            }) => Err(ClientError::Version {
                device,
                host: link::VERSION,
            }),
            Err(e) => Err(e),
        }
    }

    /// The device, its limits and its bank.
    pub fn info(&mut self) -> Result<DeviceInfo, ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Info, timeout, RETRIES, |r| match r {
            Reply::Info(i) => Some(DeviceInfo {
                link_version: i.link_version,
                firmware: i.firmware.to_owned(),
                layout: i.layout.to_owned(),
                layout_hash: i.layout_hash,
                full_scale_ma: i.full_scale_ma,
                limits: i.limits,
                max_message: i.max_message,
                max_chunk: i.max_chunk,
                bank_capacity: i.bank_capacity,
                bank: i.bank,
            }),
            _ => None,
        })
    }

    /// One slot of the bank.
    pub fn slot(&mut self, slot: u8) -> Result<SlotEntry, ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Slot { slot }, timeout, RETRIES, |r| match r {
            Reply::Slot(s) => Some(SlotEntry {
                slot: s.slot,
                name: s.name.to_owned(),
                duration_ms: s.duration_ms,
                playback_ms: s.playback_ms,
                playable: s.playable,
            }),
            _ => None,
        })
    }

    /// The device's state now.
    pub fn status(&mut self) -> Result<StatusReport, ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Status, timeout, RETRIES, |r| match r {
            Reply::Status(s) => Some(s),
            _ => None,
        })
    }

    /// Plays a slot. Not retried: a play that got through twice would restart.
    pub fn play(&mut self, slot: u8) -> Result<Started, ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Play { slot }, timeout, 0, |r| match r {
            Reply::Play { tick, now, .. } => Some(Started { tick, now }),
            _ => None,
        })
    }

    /// Stops what plays; returns what was stopped and the tick its ramp began.
    pub fn stop(&mut self) -> Result<(Option<Source>, u32), ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Stop, timeout, RETRIES, |r| match r {
            Reply::Stop { source, tick } => Some((source, tick)),
            _ => None,
        })
    }

    /// Reads `len` bytes of the bank region from `offset`.
    pub fn read_bank(
        &mut self,
        offset: u32,
        len: u32,
        mut progress: impl FnMut(Progress),
    ) -> Result<Vec<u8>, ClientError> {
        let chunk = self.chunk_len()?;
        let mut out = Vec::with_capacity(len as usize);
        while (out.len() as u32) < len {
            let at = offset + out.len() as u32;
            let want = (len - out.len() as u32).min(chunk as u32) as u16;
            let timeout = self.timeouts.reply;
            let bytes = self.call(
                Command::BankRead {
                    offset: at,
                    len: want,
                },
                timeout,
                RETRIES,
                |r| match r {
                    Reply::BankData { offset, bytes } if offset == at => Some(bytes.to_vec()),
                    _ => None,
                },
            )?;
            if bytes.is_empty() {
                return Err(ClientError::Protocol("a bank read returned no bytes"));
            }
            out.extend_from_slice(&bytes[..bytes.len().min(want as usize)]);
            progress(Progress {
                done: out.len() as u64,
                total: u64::from(len),
            });
        }
        Ok(out)
    }

    /// Uploads a bank image: erase, chunks, commit. The device checks the image
    /// (length, CRC, format, layout) at the commit and then restarts into it; call
    /// [`Client::verify`] once it is back. A cut anywhere leaves the old bank or
    /// none, never part of this one (the device's rule).
    pub fn upload(
        &mut self,
        image: &[u8],
        mut progress: impl FnMut(Progress),
    ) -> Result<u8, ClientError> {
        let len =
            u32::try_from(image.len()).map_err(|_| ClientError::Protocol("image too long"))?;
        let crc = touch_protocol::container::crc32(image);
        let chunk = self.chunk_len()?;
        let erase = self.timeouts.erase;
        self.call(Command::BankBegin { len, crc }, erase, 0, |r| match r {
            Reply::BankBegin { len: l } if l == len => Some(()),
            _ => None,
        })?;
        let total = u64::from(len);
        let mut offset = 0u32;
        progress(Progress { done: 0, total });
        while offset < len {
            let end = (offset as usize + chunk).min(image.len());
            let bytes = &image[offset as usize..end];
            let timeout = self.timeouts.reply;
            let r = self.call(
                Command::BankChunk { offset, bytes },
                timeout,
                RETRIES,
                |r| match r {
                    Reply::BankChunk { next } => Some(next),
                    _ => None,
                },
            );
            let next = match r {
                Ok(next) => next,
                // A retry after a lost acknowledgement: the device already has it.
                Err(ClientError::Refused {
                    error: LinkError::OutOfOrder { expected },
                    ..
                }) if expected == end as u32 => expected,
                Err(e) => return Err(e),
            };
            if next != end as u32 {
                return Err(ClientError::Protocol(
                    "a chunk acknowledged at another offset",
                ));
            }
            offset = next;
            progress(Progress {
                done: u64::from(offset),
                total,
            });
        }
        let timeout = self.timeouts.erase;
        let (got, slots) = self.call(Command::BankCommit, timeout, 0, |r| match r {
            Reply::BankCommit { crc, slots } => Some((crc, slots)),
            _ => None,
        })?;
        if got != crc {
            return Err(ClientError::Verify(VerifyError::CommitCrc {
                expected: crc,
                got,
            }));
        }
        Ok(slots)
    }

    /// Abandons an upload in progress (the region stays erased).
    pub fn abort_upload(&mut self) -> Result<(), ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::BankAbort, timeout, RETRIES, |r| match r {
            Reply::BankAbort => Some(()),
            _ => None,
        })
    }

    /// Waits for a restarted device to answer (`hello`), for at most the restart
    /// timeout. The device restarts after its reply to a commit went out: the first
    /// moments are left to it, so that the old firmware cannot answer.
    pub fn reconnect(&mut self) -> Result<String, ClientError> {
        let start = self.transport.now();
        // A port that vanished with the restart (USB) fails here: the hello says so.
        let _ = self.pump(RESTART_GRACE);
        self.decoder.reset();
        self.inbox.clear();
        loop {
            match self.hello() {
                Ok(firmware) => return Ok(firmware),
                Err(ClientError::Timeout { .. } | ClientError::Unreadable { .. })
                    if self.transport.now() - start < self.timeouts.restart => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// Checks that the device plays `image` from its bank region: its summary says
    /// so, and every byte read back is the image's. (Bytes, not a CRC of them: a
    /// bank ends with its own CRC, so the CRC-32 of any intact bank image is the
    /// same constant, 0x2144DF1C.)
    pub fn verify(
        &mut self,
        image: &[u8],
        progress: impl FnMut(Progress),
    ) -> Result<(), ClientError> {
        let expected = image.len() as u32;
        match self.info()?.bank {
            BankState::Flashed(s) if s.len == expected => {}
            BankState::Flashed(s) => {
                return Err(ClientError::Verify(VerifyError::Length {
                    expected,
                    got: s.len,
                }))
            }
            _ => return Err(ClientError::Verify(VerifyError::NotFlashed)),
        }
        let back = self.read_bank(0, expected, progress)?;
        if let Some(at) = (0..image.len()).find(|&i| back.get(i) != Some(&image[i])) {
            return Err(ClientError::Verify(VerifyError::Byte(at)));
        }
        Ok(())
    }

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
            Reply::StreamBegin { capacity } => Some(capacity),
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
            let (dev_next, dev_room) = self.call(
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
            )?;
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

    /// The next event, waiting at most `timeout`; `None` if none came.
    pub fn next_event(&mut self, timeout: Duration) -> Result<Option<Stamped>, ClientError> {
        if let Some(e) = self.events.pop_front() {
            return Ok(Some(e));
        }
        let start = self.transport.now();
        loop {
            let left = timeout.saturating_sub(self.transport.now() - start);
            self.receive(left, |_| false)?;
            if let Some(e) = self.events.pop_front() {
                return Ok(Some(e));
            }
            if self.transport.now() - start >= timeout {
                return Ok(None);
            }
        }
    }

    /// Reads what the device sends for `d`, queueing its events.
    pub fn pump(&mut self, d: Duration) -> Result<(), ClientError> {
        let start = self.transport.now();
        while self.transport.now() - start < d {
            let left = d.saturating_sub(self.transport.now() - start);
            self.receive(left, |_| false)?;
        }
        Ok(())
    }

    fn chunk_len(&mut self) -> Result<usize, ClientError> {
        // Every device of this link version takes MAX_CHUNK; a smaller one says so.
        let info = self.info()?;
        Ok(usize::from(info.max_chunk).clamp(link::KEYFRAME_LEN, link::MAX_CHUNK))
    }

    /// Sends `command` and waits for its reply; `take` turns the right reply into
    /// the result (`None`: the wrong kind). Retries `retries` times when nothing
    /// came back or the device could not read the frame.
    fn call<R>(
        &mut self,
        command: Command<'_>,
        timeout: Duration,
        retries: u32,
        mut take: impl FnMut(Reply<'_>) -> Option<R>,
    ) -> Result<R, ClientError> {
        let name = command_name(&command);
        let mut attempt = 0;
        loop {
            self.seq = self.seq.wrapping_add(1);
            let seq = self.seq;
            let mut wire = [0u8; link::MAX_ENCODED];
            let n = link::encode(&Request { seq, command }, &mut wire)
                .map_err(|_| ClientError::Protocol("a request too long to send"))?;
            self.transport.write_all(&wire[..n])?;
            match self.await_reply(seq, name, timeout, &mut take) {
                Err(ClientError::Timeout { .. } | ClientError::Unreadable { .. })
                    if attempt < retries =>
                {
                    attempt += 1;
                }
                other => return other,
            }
        }
    }

    fn await_reply<R>(
        &mut self,
        seq: u16,
        command: &'static str,
        timeout: Duration,
        take: &mut impl FnMut(Reply<'_>) -> Option<R>,
    ) -> Result<R, ClientError> {
        let start = self.transport.now();
        let mut result: Option<Result<R, ClientError>> = None;
        let mut unreadable = None;
        loop {
            let left = timeout.saturating_sub(self.transport.now() - start);
            self.receive(left, |message| match message {
                Message::Reply { seq: s, reply } if s == seq => {
                    result = Some(take(reply).ok_or(ClientError::UnexpectedReply { command }));
                    true
                }
                Message::Refused { seq: s, error } if s == seq => {
                    result = Some(Err(ClientError::Refused { command, error }));
                    true
                }
                Message::Unreadable(error) => {
                    unreadable = Some(error);
                    false
                }
                _ => false,
            })?;
            if let Some(r) = result {
                return r;
            }
            if self.transport.now() - start >= timeout {
                return Err(match unreadable {
                    Some(error) => ClientError::Unreadable { command, error },
                    None => ClientError::Timeout {
                        command,
                        waited: timeout,
                    },
                });
            }
        }
    }

    /// Reads bytes for at most `timeout` and hands each decoded message to `seen`
    /// (events are queued instead); returns once a read brought whole messages (or
    /// `seen` returned true), or at the timeout.
    fn receive(
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
                    reply: Reply::Stop {
                        source: None,
                        tick: 1,
                    },
                }),
                frame(&Message::Reply {
                    seq,
                    reply: Reply::Stop {
                        source: Some(Source::Slot(2)),
                        tick: 9,
                    },
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
                Command::Stop => Reply::Stop {
                    source: None,
                    tick: 3,
                },
                _ => Reply::Play {
                    slot: 0,
                    tick: 4,
                    now: true,
                },
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
