//! The host's end of the link: requests with sequence numbers, replies matched to
//! them, events queued, timeouts, and the multi-frame operations (upload, stream).

use std::collections::VecDeque;
use std::time::{Duration, SystemTime};

use touch_protocol::link::cobs::Decoder;
use touch_protocol::link::{
    self, Command, Event, FrameError, LinkError, PlayReply, Reply, Source, StatusReport, StopReply,
    StreamStop,
};

use super::Transport;

mod frames;
mod stream;
mod upload;

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
    /// The device stopped a stream before every keyframe was sent (its outputs
    /// ramp to 0 A): the reason its `StreamStopped` event gave.
    #[error("the device stopped the stream: {0:?}")]
    StreamStopped(StreamStop),
    /// The device restarted (a power cut, a reset) before it answered `command`:
    /// it answered a later request instead, or no longer knew the upload. What
    /// the command began on it is lost (a commit's bank may still be in place:
    /// [`Client::verify`] tells).
    #[error("the device restarted before it answered {command}")]
    Restarted {
        /// The command's name.
        command: &'static str,
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

/// What a sleeve says about itself: the wire's [`link::Info`], its text owned.
pub type DeviceInfo = link::Info<String>;

/// One slot of the sleeve's bank: the wire's [`link::SlotInfo`], its name owned.
pub type SlotEntry = link::SlotInfo<String>;

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
            Reply::Info(i) => Some(i.map_text(str::to_owned)),
            _ => None,
        })
    }

    /// One slot of the bank.
    pub fn slot(&mut self, slot: u8) -> Result<SlotEntry, ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Slot { slot }, timeout, RETRIES, |r| match r {
            Reply::Slot(s) => Some(s.map_text(str::to_owned)),
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
            Reply::Play(PlayReply { tick, now, .. }) => Some(Started { tick, now }),
            _ => None,
        })
    }

    /// Stops what plays; returns what was stopped and the tick its ramp began.
    pub fn stop(&mut self) -> Result<(Option<Source>, u32), ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::Stop, timeout, RETRIES, |r| match r {
            Reply::Stop(StopReply { source, tick }) => Some((source, tick)),
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
}

#[cfg(test)]
mod tests;
