//! The link server: frames in, replies and events out.
//!
//! It runs outside the tick (a thread-mode task on the target). What touches playback
//! (play, stop, status, streams, the upload's lock) goes to the tick as a [`Control`]
//! through the lock-free [`LinkPort`], and comes back as an [`Answer`]: the same
//! controller, player and thermal state as the buttons decide. What does not (info,
//! slots, bank reads and writes) is answered here.

use touch_protocol::link::{
    self, cobs, BankState, Busy, Command, FrameError, Info, LinkError, Message, Reply, Request,
    SlotInfo, StatusReport, StreamParams, TickReply, MAX_CHUNK, MAX_ENCODED, MAX_MESSAGE,
    MAX_STREAM_KEYFRAMES,
};
use touch_protocol::{Bank, Player, Thermal};

use super::bank::{BankWriter, Flash};
use super::port::{Answer, Control, LinkPort, Snapshot, STAGED_STREAM, STAGED_STREAM_ONE};
use crate::output::{device_config, LAYOUT_HASH};

/// What the device says about itself in `Info`.
#[derive(Debug, Clone, Copy)]
pub struct Identity<'a> {
    /// The firmware's version.
    pub firmware: &'a str,
    /// The layout's name (its file's `id`).
    pub layout: &'a str,
    /// The layout's geometry hash.
    pub layout_hash: u32,
    /// The bank the device booted with.
    pub bank: BankState,
    /// That bank, for slot names and durations (`None` if refused).
    pub slots: Option<Bank<'a>>,
}

/// An upload whose host sent none of its requests (begin, chunk, commit, abort) for
/// this long is abandoned: the host is gone, and the device restarts (into the
/// built-in bank: the region was erased at the upload's begin) rather than stay
/// locked, with nothing playable. Other requests (another program's `Info`, a
/// `Play` refused as busy) do not keep it alive. Longer than the erase at the
/// upload's begin (two 128 KB sectors, 4 s at most by the datasheet) and any pause
/// of a host that is still there.
pub const UPLOAD_IDLE_MS: u64 = 10_000;

/// The server (see the module docs).
pub struct LinkServer<'a, F: Flash> {
    port: LinkPort<'a, 'a>,
    flash: F,
    writer: BankWriter,
    id: Identity<'a>,
    rx: cobs::Decoder<MAX_ENCODED>,
    tx: [u8; MAX_ENCODED],
    /// A `BankBegin` waiting for the tick to lock the bank: seq, len, crc.
    begin: Option<(u16, u32, u32)>,
    /// The bank region belongs to an upload until the restart.
    locked: bool,
    /// The next stream keyframe index, while a stream takes data.
    stream_next: Option<u32>,
    /// The last stream begun, and its first keyframe once it came: its player is
    /// built here, once its first two keyframes are in.
    stream: Option<(StreamParams, Option<[i16; 8]>)>,
    restart: bool,
    /// When bytes last came from the host, ms on the caller's clock.
    heard_ms: u64,
    /// When the upload's last request came, ms on the same clock.
    upload_ms: u64,
    /// Frames dropped by the transport (wrapping), and those answered.
    dropped: u32,
    overruns: u32,
}

impl<'a, F: Flash> LinkServer<'a, F> {
    /// A server over the link's end of the queues and the bank region's flash.
    pub fn new(port: LinkPort<'a, 'a>, flash: F, id: Identity<'a>) -> Self {
        LinkServer {
            port,
            flash,
            writer: BankWriter::new(),
            id,
            rx: cobs::Decoder::new(),
            tx: [0; MAX_ENCODED],
            begin: None,
            locked: false,
            stream_next: None,
            stream: None,
            restart: false,
            heard_ms: 0,
            upload_ms: 0,
            dropped: 0,
            overruns: 0,
        }
    }

    /// True once the device should restart (after a committed or aborted upload),
    /// when the last reply went out.
    pub fn restart_requested(&self) -> bool {
        self.restart
    }

    /// Notes that bytes came from the host at `now_ms` (ms on a monotonic clock, the
    /// one [`LinkServer::restart_due`] is asked with).
    pub fn heard(&mut self, now_ms: u64) {
        self.heard_ms = now_ms;
    }

    /// True once the device should restart, at `now_ms`: after a committed or
    /// aborted upload ([`LinkServer::restart_requested`]), or an upload that owns
    /// the bank and got none of its requests for [`UPLOAD_IDLE_MS`].
    pub fn restart_due(&self, now_ms: u64) -> bool {
        let abandoned = self.locked && now_ms.saturating_sub(self.upload_ms) > UPLOAD_IDLE_MS;
        self.restart || abandoned
    }

    /// The bank region's flash.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// True while an upload owns the bank region (nothing from the bank plays).
    pub fn locked(&self) -> bool {
        self.locked
    }

    /// Bytes from the wire; every frame they complete is answered through `out`
    /// (whole encoded frames, ready to send).
    pub fn receive(&mut self, bytes: &[u8], out: &mut dyn FnMut(&[u8])) {
        for &b in bytes {
            // The frame is copied out: the request borrows it while the reply borrows
            // the server.
            let mut copy = [0u8; link::MAX_FRAME];
            let n = match self.rx.feed(b) {
                cobs::Feed::Pending => continue,
                cobs::Feed::Dropped(e) => {
                    self.emit(&Message::Unreadable(FrameError::from(e)), out);
                    continue;
                }
                cobs::Feed::Frame(frame) if frame.len() > copy.len() => {
                    self.emit(&Message::Unreadable(FrameError::TooLong), out);
                    continue;
                }
                cobs::Feed::Frame(frame) => {
                    copy[..frame.len()].copy_from_slice(frame);
                    frame.len()
                }
            };
            self.handle_frame(&copy[..n], out);
        }
    }

    /// Counts the frames a transport dropped unread (its receive buffer was full),
    /// `total` since boot (wrapping): each is answered `Unreadable(Overrun)` by
    /// [`LinkServer::poll_one`], so that every request gets an answer, these
    /// without their `seq`.
    pub fn dropped(&mut self, total: u32) {
        self.dropped = total;
    }

    fn handle_frame(&mut self, frame: &[u8], out: &mut dyn FnMut(&[u8])) {
        match link::decode::<Request>(frame) {
            Ok(r) => self.handle(r, out),
            Err(e) => self.emit(&Message::Unreadable(e), out),
        }
    }

    /// Answers one request: what touches playback goes to the tick, the rest is
    /// answered here.
    #[inline(never)]
    pub fn handle(&mut self, r: Request<'_>, out: &mut dyn FnMut(&[u8])) {
        let seq = r.seq;
        if matches!(
            r.command,
            Command::BankBegin { .. }
                | Command::BankChunk { .. }
                | Command::BankCommit
                | Command::BankAbort
        ) {
            self.upload_ms = self.heard_ms;
        }
        match r.command {
            Command::Hello { version } if version == link::VERSION => {
                let firmware = self.id.firmware;
                let reply = Reply::Hello {
                    version: link::VERSION,
                    firmware,
                };
                self.reply(seq, reply, out)
            }
            Command::Hello { .. } => {
                let device = link::VERSION;
                self.refuse(seq, LinkError::UnsupportedVersion { device }, out)
            }
            Command::Info => self.reply(seq, Reply::Info(self.info()), out),
            Command::Slot { slot } => match self.slot_info(slot) {
                Ok(info) => {
                    let m = Message::Reply {
                        seq,
                        reply: Reply::Slot(info),
                    };
                    encode_into(&m, &mut self.tx, out);
                }
                Err(e) => self.refuse(seq, e, out),
            },
            Command::BankRead { offset, len } => self.bank_read(seq, offset, len, out),
            Command::BankBegin { len, crc } => self.bank_begin(seq, len, crc, out),
            Command::BankChunk { offset, bytes } => {
                if bytes.len() > MAX_CHUNK {
                    return self.refuse(seq, LinkError::Malformed, out);
                }
                match self.writer.chunk(&mut self.flash, offset, bytes) {
                    Ok(next) => self.reply(seq, Reply::BankChunk { next }, out),
                    Err(e) => self.refuse(seq, e, out),
                }
            }
            Command::BankCommit => match self.writer.commit(&mut self.flash) {
                Ok(c) => {
                    self.restart = true;
                    let (crc, slots) = (c.crc, c.slots);
                    self.reply(seq, Reply::BankCommit { crc, slots }, out)
                }
                Err(e) => self.refuse(seq, e, out),
            },
            Command::BankAbort => match self.writer.abort() {
                Ok(()) => {
                    self.restart = true;
                    self.reply(seq, Reply::BankAbort, out)
                }
                Err(e) => self.refuse(seq, e, out),
            },
            Command::Play { slot } => {
                // Its player first, so that the tick that starts it only takes it.
                self.stage(slot);
                self.forward(seq, Control::Play { seq, slot }, out)
            }
            Command::Stop => {
                self.stream_next = None;
                self.forward(seq, Control::Stop { seq }, out)
            }
            Command::Status => self.forward(seq, Control::Status { seq }, out),
            Command::StreamBegin(params) => {
                if let Err(e) = params.validate() {
                    return self.refuse(seq, e, out);
                }
                self.stream = Some((params, None));
                self.forward(seq, Control::StreamBegin { seq, params }, out)
            }
            Command::StreamData { index, keyframes } => match self.stream_data(index, keyframes) {
                Ok((next, room)) => self.reply(seq, Reply::StreamData { next, room }, out),
                Err(e) => self.refuse(seq, e, out),
            },
            Command::StreamEnd => self.stream_end(seq, out),
        }
    }

    /// Replies to the request `seq`.
    fn reply(&mut self, seq: u16, reply: Reply<'_>, out: &mut dyn FnMut(&[u8])) {
        self.emit(&Message::Reply { seq, reply }, out)
    }

    /// Refuses the request `seq`.
    fn refuse(&mut self, seq: u16, error: LinkError, out: &mut dyn FnMut(&[u8])) {
        self.emit(&Message::Refused { seq, error }, out)
    }

    /// What the device says about itself.
    fn info(&self) -> Info<&'a str> {
        let d = device_config();
        Info {
            link_version: link::VERSION,
            firmware: self.id.firmware,
            layout: self.id.layout,
            layout_hash: self.id.layout_hash,
            full_scale_ma: d.full_scale_ma,
            limits: d.limits,
            max_message: MAX_MESSAGE as u16,
            max_chunk: MAX_CHUNK as u16,
            bank_capacity: touch_protocol::bank::REGION_LEN as u32,
            bank: self.id.bank,
        }
    }

    /// A `BankRead`: up to [`MAX_CHUNK`] bytes of the bank region from `offset`.
    fn bank_read(&mut self, seq: u16, offset: u32, len: u16, out: &mut dyn FnMut(&[u8])) {
        let region = self.flash.region();
        let (offset_us, len_us) = (offset as usize, usize::from(len));
        if len_us > MAX_CHUNK {
            // A length no reply may carry breaks the command's own rule.
            return self.refuse(seq, LinkError::Malformed, out);
        }
        if offset_us > region.len() {
            return self.refuse(seq, LinkError::OutOfRange, out);
        }
        let end = (offset_us + len_us).min(region.len());
        let m = Message::Reply {
            seq,
            reply: Reply::BankData {
                offset,
                bytes: &region[offset_us..end],
            },
        };
        // The reply borrows the flash: encoded apart from `emit`'s borrow of all of
        // the server.
        encode_into(&m, &mut self.tx, out);
    }

    /// A `BankBegin`: the tick locks the bank first (nothing from it may play while
    /// the upload erases and writes it), then [`LinkServer::poll`] erases and replies.
    fn bank_begin(&mut self, seq: u16, len: u32, crc: u32, out: &mut dyn FnMut(&[u8])) {
        if self.locked {
            // The bank is already the upload's: start over at once.
            self.begin = Some((seq, len, crc));
            self.erase_and_reply(out);
        } else if self.begin.is_some() {
            self.refuse(seq, LinkError::Busy(Busy::Uploading), out)
        } else if self.port.send(Control::Lock { seq }).is_ok() {
            self.begin = Some((seq, len, crc));
        } else {
            self.refuse(seq, LinkError::QueueFull, out)
        }
    }

    /// A `StreamEnd`, forwarded to the tick; a stream of one keyframe gets its
    /// player here first, as a stream's second keyframe does.
    fn stream_end(&mut self, seq: u16, out: &mut dyn FnMut(&[u8])) {
        if self.stream_next == Some(1) {
            // A stream of one keyframe: its player starts from it alone.
            if let Some((params, Some(first))) = self.stream {
                self.stage_stream(STAGED_STREAM_ONE, &params, first, first);
            }
        }
        self.stream_next = None;
        self.forward(seq, Control::StreamEnd { seq }, out)
    }

    /// Forwards a command to the tick (refused while an upload owns the bank).
    fn forward(&mut self, seq: u16, c: Control, out: &mut dyn FnMut(&[u8])) {
        let starts = matches!(c, Control::Play { .. } | Control::StreamBegin { .. });
        let error = if starts && (self.locked || self.begin.is_some()) {
            Some(LinkError::Busy(Busy::Uploading))
        } else if self.port.send(c).is_err() {
            // Four commands already wait for the tick: the host sends faster than
            // it reads replies.
            Some(LinkError::QueueFull)
        } else {
            None
        };
        if let Some(error) = error {
            self.emit(&Message::Refused { seq, error }, out);
        }
    }

    fn stream_data(&mut self, index: u32, keyframes: &[u8]) -> Result<(u32, u16), LinkError> {
        let expected = self.stream_next.ok_or(LinkError::NoStream)?;
        if !keyframes.len().is_multiple_of(link::KEYFRAME_LEN) || keyframes.len() > MAX_CHUNK {
            return Err(LinkError::Malformed);
        }
        if index != expected {
            return Err(LinkError::StreamGap { expected });
        }
        let n = keyframes.len() / link::KEYFRAME_LEN;
        let room = self.port.keyframe_room();
        if n > room {
            return Err(LinkError::StreamFull { room: room as u16 });
        }
        for i in 0..n.min(MAX_STREAM_KEYFRAMES) {
            if let Some(k) = link::stream_keyframe(keyframes, i) {
                // The player from the stream's first two keyframes, for the tick to
                // take when it starts the stream: staged before the second is
                // queued, as the tick starts the stream once two are.
                match (expected + i as u32, self.stream) {
                    (0, Some((params, _))) => self.stream = Some((params, Some(k))),
                    (1, Some((params, Some(first)))) => {
                        self.stage_stream(STAGED_STREAM, &params, first, k)
                    }
                    _ => {}
                }
                let _ = self.port.push_keyframe(k);
            }
        }
        self.port.fed();
        let next = expected.wrapping_add(n as u32);
        self.stream_next = Some(next);
        Ok((next, (room - n) as u16))
    }

    fn slot_info(&self, slot: u8) -> Result<SlotInfo<&'a str>, LinkError> {
        if self.locked || self.begin.is_some() {
            return Err(LinkError::Busy(Busy::Uploading));
        }
        let bank = self.id.slots.ok_or(LinkError::NoBank)?;
        let slots = bank.len() as u8;
        let s = bank
            .slot(usize::from(slot))
            .map_err(|_| LinkError::NoSuchSlot { slot, slots })?;
        Ok(SlotInfo {
            slot,
            name: s.name(),
            duration_ms: s.duration_ms(),
            playback_ms: s.header().playback_ms(),
            playable: s.check_layout(LAYOUT_HASH).is_ok(),
        })
    }

    /// Builds the player for `slot` (from a cold coil: the tick hands it the heat
    /// at the start) and stages it for the tick. Not while an upload owns the bank
    /// region: nothing from it may be read for playback then.
    fn stage(&mut self, slot: u8) {
        if self.locked || self.begin.is_some() {
            return;
        }
        let Some(bank) = self.id.slots else {
            return;
        };
        self.port.stage(slot, || {
            let s = bank.slot(usize::from(slot)).ok()?;
            s.check_layout(LAYOUT_HASH).ok()?;
            Some(Player::with_thermal(&s, &device_config(), Thermal::COLD))
        });
    }

    /// Builds a stream's player from its first keyframes (from a cold coil: the tick
    /// hands it the heat at the start) and stages it as `tag`.
    fn stage_stream(&mut self, tag: u8, params: &StreamParams, first: [i16; 8], second: [i16; 8]) {
        // One staged under this tag is an earlier stream's, stopped before it
        // started: never this one's.
        self.port.unstage(tag);
        self.port.stage(tag, || {
            Some(Player::live(
                params,
                first,
                second,
                &device_config(),
                Thermal::COLD,
            ))
        });
    }

    /// Forwards what the tick answered, builds the player the tick wants ready,
    /// and does an upload's erase once the tick has locked the bank.
    pub fn poll(&mut self, out: &mut dyn FnMut(&[u8])) {
        while self.poll_one(out) {}
    }

    /// As [`LinkServer::poll`], for one answer at most (one frame through `out`):
    /// a frame dropped unread ([`LinkServer::dropped`]), else the tick's next. A
    /// transport calls it while it has room for a frame, so that no answer is
    /// dropped on a full wire. False when none waited.
    #[inline(never)]
    pub fn poll_one(&mut self, out: &mut dyn FnMut(&[u8])) -> bool {
        if let Some(slot) = self.port.wanted() {
            if self.port.staged() != Some(slot) {
                self.stage(slot);
            }
        }
        if self.overruns != self.dropped {
            self.overruns = self.overruns.wrapping_add(1);
            self.emit(&Message::Unreadable(FrameError::Overrun), out);
            return true;
        }
        let Some(a) = self.port.receive() else {
            return false;
        };
        match a {
            Answer::Reply(seq, reply) => {
                if matches!(reply, TickReply::StreamBegin(_)) {
                    self.stream_next = Some(0);
                }
                let reply = reply.into();
                self.emit(&Message::Reply { seq, reply }, out);
            }
            Answer::Refused(seq, error) => {
                if matches!(self.begin, Some((s, ..)) if s == seq) {
                    self.begin = None;
                }
                self.emit(&Message::Refused { seq, error }, out);
            }
            Answer::Status(seq) => {
                let reply = Reply::Status(self.status(&self.port.snapshot()));
                self.emit(&Message::Reply { seq, reply }, out);
            }
            Answer::Locked(_) => {
                self.locked = true;
                self.erase_and_reply(out);
            }
            Answer::Event(tick, event) => {
                if matches!(
                    event,
                    link::Event::StreamStopped(_)
                        | link::Event::Finished(link::Source::Stream)
                        | link::Event::TooHot {
                            source: link::Source::Stream,
                            ..
                        }
                ) {
                    self.stream_next = None;
                }
                self.emit(&Message::Event { tick, event }, out);
            }
        }
        true
    }

    fn erase_and_reply(&mut self, out: &mut dyn FnMut(&[u8])) {
        let Some((seq, len, crc)) = self.begin.take() else {
            return;
        };
        let m = match self.writer.begin(&mut self.flash, len, crc) {
            Ok(()) => Message::Reply {
                seq,
                reply: Reply::BankBegin { len },
            },
            Err(error) => Message::Refused { seq, error },
        };
        self.emit(&m, out);
    }

    /// The `Status` reply: the heat against the budget a start of the selected
    /// slot is judged by, and the cooldown that start waits for (the numbers its
    /// refusal would give).
    fn status(&self, s: &Snapshot) -> StatusReport {
        let limits = s.start_limits;
        let heat = s.thermal.heat_ma2ms();
        StatusReport {
            tick: s.tick,
            playing: s.playing,
            stopping: s.stopping,
            selected: s.selected,
            heat_permille: core::array::from_fn(|c| budget_permille(heat[c], &limits)),
            cooldown_ms: s
                .thermal
                .check_start(&limits)
                .err()
                .map_or(0, |h| h.cooldown_ms),
            faults: s.faults,
            last_fault: s.last_fault,
            upload: self.writer.progress(),
        }
    }

    fn emit(&mut self, m: &Message<'_>, out: &mut dyn FnMut(&[u8])) {
        encode_into(m, &mut self.tx, out);
    }
}

/// Encodes and hands out one frame. Every message the server builds fits
/// [`MAX_ENCODED`] (pinned by the protocol's tests), so an error is not expected; if
/// one came, the host would see no answer and time out, never a wrong one.
fn encode_into(m: &Message<'_>, tx: &mut [u8; MAX_ENCODED], out: &mut dyn FnMut(&[u8])) {
    if let Ok(n) = link::encode(m, tx) {
        out(&tx[..n]);
    }
}

/// Heat as per mille of the I^2 t budget of `limits` (mA^2 s, the bucket holds
/// mA^2 ms), as [`touch_protocol::Thermal::check_start`] gives it in a refusal.
fn budget_permille(heat_ma2ms: u64, limits: &touch_protocol::Limits) -> u16 {
    let budget = u64::from(limits.i2t_budget_ma2s)
        .saturating_mul(1000)
        .max(1);
    (heat_ma2ms.saturating_mul(1000) / budget).min(u64::from(u16::MAX)) as u16
}

/// The firmware's version, as `Info` and `Hello` give it.
pub const FIRMWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// The layout this firmware drives, by name.
pub const LAYOUT_NAME: &str = touch_protocol::layout::SLEEVE_NAME;

/// The boot's view of the bank for `Info`: which bank plays (or why none), and the
/// bank itself. `source` is what [`crate::boot::bank_source`] chose, `builtin` the
/// built-in bank it may have chosen.
pub fn identity<'a>(
    source: &'a [u8],
    builtin: &'a [u8],
    checked: Result<Bank<'a>, crate::boot::BootError>,
) -> Identity<'a> {
    let bank = match checked {
        Ok(b) => {
            let summary = link::BankSummary {
                len: b.as_bytes().len() as u32,
                crc: super::bank::stored_crc(b.as_bytes()),
                slots: b.len() as u8,
            };
            if core::ptr::eq(source, builtin) {
                BankState::Builtin(summary)
            } else {
                BankState::Flashed(summary)
            }
        }
        Err(e) => BankState::Refused { blinks: e.blinks() },
    };
    Identity {
        firmware: FIRMWARE_VERSION,
        layout: LAYOUT_NAME,
        layout_hash: LAYOUT_HASH,
        bank,
        slots: checked.ok(),
    }
}
