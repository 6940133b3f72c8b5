//! The link end to end: the host's client (`touchc_link`) against the firmware's
//! link server (`sleeve_firmware::link::sim`, the engine, controller, bank writer and
//! server as the firmware wires them) over an in-memory transport, in device time.
//!
//! The transport runs the device: a read that waits ticks it one millisecond at a
//! time, so every timeout and deadline below is the device's 1 kHz tick.

use std::io;
use std::time::Duration;

use sleeve_firmware::link::sim::Device;
use sleeve_firmware::output::{device_config, Frame, IDLE_FRAME, LAYOUT_HASH};
use touch_protocol::link::{
    self, BankState, Command, Event, LinkError, Message, Request, Source, StreamStop,
};
use touch_protocol::stimulus;
use touch_protocol::{bank, Bank, Limits, Player, Status, Stimulus, CHANNELS};
use touchc_link::{Client, ClientError, Transport};

const EMOJI: &[u8] = include_bytes!("../../examples/emoji/emoji.bank");

/// The device on the other end of the wire, driven by the host's reads.
struct Sim {
    dev: Device,
    /// Device milliseconds so far.
    ms: u64,
    /// Bytes the device sent that the host has not read.
    pending: Vec<u8>,
    /// Writes the host may still make before the cable is pulled.
    writes_left: Option<usize>,
}

impl Sim {
    fn new(region: &[u8]) -> Sim {
        Sim {
            dev: Device::boot(region, EMOJI),
            ms: 0,
            pending: Vec::new(),
            writes_left: None,
        }
    }

    fn tick(&mut self) {
        self.dev.tick();
        self.ms += 1;
        self.pending.extend(self.dev.read());
    }

    /// Runs the device with nobody listening.
    fn run(&mut self, ms: u64) {
        for _ in 0..ms {
            self.tick();
        }
    }
}

impl Transport for Sim {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        match &mut self.writes_left {
            Some(0) => return Err(io::ErrorKind::BrokenPipe.into()),
            Some(n) => *n -= 1,
            None => {}
        }
        self.dev.write(bytes);
        self.pending.extend(self.dev.read());
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let until = self.ms + timeout.as_millis() as u64;
        while self.pending.is_empty() && self.ms < until {
            self.tick();
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }

    fn now(&self) -> Duration {
        Duration::from_millis(self.ms)
    }
}

/// The bank region: `image` at its start, the rest erased.
fn region(image: &[u8]) -> Vec<u8> {
    let mut r = vec![0xFF; bank::REGION_LEN];
    r[..image.len()].copy_from_slice(image);
    r
}

fn sleeve(image: &[u8]) -> Client<Sim> {
    let mut c = Client::new(Sim::new(&region(image)));
    c.hello().unwrap();
    c
}

fn dev(c: &mut Client<Sim>) -> &mut Sim {
    c.transport_mut()
}

/// The host player's codes for `slot` of `image`, first tick to the finished one.
fn host_codes(image: &[u8], slot: usize) -> Vec<Frame> {
    let bank = Bank::decode(image).unwrap();
    let s = bank.slot(slot).unwrap();
    let mut player = Player::new(&s, &device_config());
    let mut out = Vec::new();
    loop {
        let t = player.tick();
        out.push(t.codes);
        if t.status == Status::Finished {
            return out;
        }
    }
}

fn at(frames: &[Frame], want: &[Frame], from: usize) -> Option<usize> {
    (from..frames.len().saturating_sub(want.len()) + 1)
        .find(|&o| frames[o..o + want.len()] == *want)
}

/// A stimulus at `level` (Q15 of 1 A) on every channel for `ms`, with `limits`,
/// keyframes every 100 ms.
fn flat(name: &str, level: i16, ms: u32, limits: Limits) -> Vec<u8> {
    flat_every(name, level, ms, limits, 100)
}

fn flat_every(name: &str, level: i16, ms: u32, limits: Limits, period: u16) -> Vec<u8> {
    let frames = vec![[level; CHANNELS]; (ms / u32::from(period)) as usize + 1];
    stimulus::Builder::new(name, period)
        .ramp_ms(40)
        .layout(touch_protocol::layout::SLEEVE_NAME, LAYOUT_HASH)
        .limits(limits)
        .encode(&frames)
        .unwrap()
}

/// Sends one raw request frame and returns the device's answer to it.
fn raw(c: &mut Client<Sim>, seq: u16, command: Command<'_>) -> Message<'static> {
    let mut wire = [0u8; link::MAX_ENCODED];
    let n = link::encode(&Request { seq, command }, &mut wire).unwrap();
    raw_bytes(c, &wire[..n])
        .into_iter()
        .next()
        .expect("an answer")
}

/// Writes bytes as they are and returns the device's messages over the next 5 ms
/// (events left out).
fn raw_bytes(c: &mut Client<Sim>, bytes: &[u8]) -> Vec<Message<'static>> {
    let d = dev(c);
    d.dev.write(bytes);
    d.pending.extend(d.dev.read());
    d.run(5);
    let wire = std::mem::take(&mut d.pending);
    let mut decoder = link::cobs::Decoder::<{ link::MAX_ENCODED }>::new();
    let mut out = Vec::new();
    for b in wire {
        if let link::cobs::Feed::Frame(f) = decoder.feed(b) {
            let m: Message<'_> = link::decode(f).unwrap();
            match m {
                Message::Event { .. } => {}
                // Owned copies of what the tests compare (no borrowed replies here).
                Message::Refused { seq, error } => out.push(Message::Refused { seq, error }),
                Message::Unreadable(e) => out.push(Message::Unreadable(e)),
                Message::Reply { seq, reply } => out.push(Message::Reply {
                    seq,
                    reply: match reply {
                        link::Reply::BankBegin { len } => link::Reply::BankBegin { len },
                        link::Reply::BankChunk { next } => link::Reply::BankChunk { next },
                        link::Reply::BankAbort => link::Reply::BankAbort,
                        link::Reply::StreamEnd => link::Reply::StreamEnd,
                        link::Reply::Stop(s) => link::Reply::Stop(s),
                        other => panic!("a reply these tests do not send for: {other:?}"),
                    },
                }),
            }
        }
    }
    out
}

#[test]
fn hello_info_slots_and_status() {
    let mut c = sleeve(EMOJI);
    let info = c.info().unwrap();
    assert_eq!(info.link_version, link::VERSION);
    assert_eq!(info.max_chunk as usize, link::MAX_CHUNK);
    assert_eq!(info.bank_capacity as usize, bank::REGION_LEN);
    let BankState::Flashed(s) = info.bank else {
        panic!("{:?}", info.bank)
    };
    let b = Bank::decode(EMOJI).unwrap();
    assert_eq!(usize::from(s.slots), b.len());
    // (The whole image's CRC-32: every intact bank has the same one, its CRC residue.)
    assert_eq!(s.len as usize, EMOJI.len());
    for (i, stim) in b.stimuli().enumerate() {
        let slot = c.slot(i as u8).unwrap();
        assert_eq!(slot.name, stim.name());
        assert_eq!(slot.duration_ms, stim.duration_ms());
        assert!(slot.playable);
    }
    let st = c.status().unwrap();
    assert_eq!(st.playing, None);
    assert_eq!(st.heat_permille, [0; 8]);
    // A slot past the bank's end is refused with the bank's size.
    match c.slot(b.len() as u8) {
        Err(ClientError::Refused {
            error: LinkError::NoSuchSlot { slot, slots },
            ..
        }) => assert_eq!((slot, usize::from(slots)), (b.len() as u8, b.len())),
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_erased_region_reports_the_builtin_bank() {
    let mut c = Client::new(Sim::new(&region(&[])));
    c.hello().unwrap();
    assert!(matches!(c.info().unwrap().bank, BankState::Builtin(_)));
}

#[test]
fn play_by_command_is_the_host_players_codes_from_the_replys_tick() {
    let mut c = sleeve(EMOJI);
    dev(&mut c).run(10);
    let started = c.play(2).unwrap();
    assert!(started.now);
    let want = host_codes(EMOJI, 2);
    c.pump(Duration::from_millis(want.len() as u64 + 20))
        .unwrap();
    let frames = dev(&mut c).dev.outputs().to_vec();
    let o = at(&frames, &want, 0).expect("slot 2 played as the host player plays it");
    assert_eq!(
        o as u32, started.tick,
        "the reply's tick is the first frame's"
    );
    let mut events = Vec::new();
    while let Some(e) = c.next_event(Duration::ZERO).unwrap() {
        events.push((e.tick, e.event));
    }
    assert!(
        events.contains(&(started.tick, Event::Started(Source::Slot(2)))),
        "{events:?}"
    );
    assert!(events
        .iter()
        .any(|&(_, e)| e == Event::Finished(Source::Slot(2))));
    // A slot that does not exist is refused, and nothing plays.
    match c.play(99) {
        Err(ClientError::Refused {
            error: LinkError::NoSuchSlot { slot: 99, .. },
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn stop_ramps_to_0a_from_the_replys_tick() {
    let mut c = sleeve(EMOJI);
    c.play(0).unwrap();
    c.pump(Duration::from_millis(300)).unwrap();
    let (source, tick) = c.stop().unwrap();
    assert_eq!(source, Some(Source::Slot(0)));
    c.pump(Duration::from_millis(100)).unwrap();
    let frames = dev(&mut c).dev.outputs();
    let rest = (tick as usize..frames.len())
        .find(|&i| frames[i] == IDLE_FRAME)
        .expect("at rest");
    assert!(
        rest - tick as usize <= 45,
        "at rest {} ms after the stop",
        rest - tick as usize
    );
    assert!(frames[rest..].iter().all(|f| *f == IDLE_FRAME));
    // Stop with nothing playing says so.
    assert_eq!(c.stop().unwrap().0, None);
}

#[test]
fn the_bank_reads_back_as_flashed() {
    let mut c = sleeve(EMOJI);
    let back = c.read_bank(0, EMOJI.len() as u32, |_| {}).unwrap();
    assert_eq!(back, EMOJI);
}

#[test]
fn upload_commit_restart_and_verify() {
    let hot = hot_bank(30_000_000);
    let mut c = sleeve(EMOJI);
    let mut seen = Vec::new();
    let slots = c.upload(&hot, |p| seen.push(p.done)).unwrap();
    assert_eq!(slots, 2);
    assert_eq!(*seen.last().unwrap(), hot.len() as u64);
    assert!(seen.windows(2).all(|w| w[0] <= w[1]));
    c.reconnect().unwrap();
    assert_eq!(dev(&mut c).dev.boots, 1, "the commit restarted the device");
    c.verify(&hot, |_| {}).unwrap();
    assert_eq!(&dev(&mut c).dev.region()[..hot.len()], &hot[..]);
    // The new bank plays.
    let started = c.play(1).unwrap();
    let want = host_codes(&hot, 1);
    c.pump(Duration::from_millis(want.len() as u64 + 10))
        .unwrap();
    let frames = dev(&mut c).dev.outputs();
    assert_eq!(at(frames, &want, 0), Some(started.tick as usize));
}

/// A bank whose slots heat the coils: near 1 A on every channel, with the I^2 t
/// budget `budget` (mA^2 s): 3 s in slot 0, 0.4 s in slot 1.
fn hot_bank(budget: u32) -> Vec<u8> {
    let limits = Limits {
        i2t_budget_ma2s: budget,
        ..Limits::SLEEVE
    };
    let long = flat("hot", 32000, 3000, limits);
    let short = flat("short", 32000, 400, limits);
    bank::encode(&[&long, &short]).unwrap()
}

/// A bank of three of the shipped emoji stimuli, in another order than the
/// built-in bank's.
fn three_emoji() -> Vec<u8> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/emoji");
    let files: Vec<Vec<u8>> = ["sadness", "love", "calming"]
        .iter()
        .map(|n| std::fs::read(dir.join(format!("{n}.touch"))).unwrap())
        .collect();
    let slices: Vec<&[u8]> = files.iter().map(Vec::as_slice).collect();
    bank::encode(&slices).unwrap()
}

#[test]
fn an_upload_cut_at_every_chunk_leaves_the_old_bank_or_none_never_a_mix() {
    let old = hot_bank(30_000_000);
    let new = three_emoji();
    let chunks = new.len().div_ceil(link::MAX_CHUNK);
    assert!(chunks >= 5, "{chunks} chunks");
    // Writes that get through after the hello: the info (for the chunk size), the
    // begin (which erases), `k` chunks; the cable is pulled before the next one.
    for allowed in 1..=chunks + 2 {
        let mut c = sleeve(&old);
        dev(&mut c).writes_left = Some(allowed);
        let r = c.upload(&new, |_| {});
        assert!(
            matches!(r, Err(ClientError::Io(_))),
            "{allowed} writes: {r:?}"
        );
        // The host is gone; the device goes on, then loses power.
        let d = dev(&mut c);
        d.run(200);
        d.dev.restart();
        d.writes_left = None;
        c.reconnect().unwrap();
        // What the region holds decides: the old bank whole (nothing erased yet),
        // or erased (the built-in bank plays), or refused; never the new one.
        let played = match c.info().unwrap().bank {
            BankState::Flashed(s) => {
                assert_eq!(
                    allowed, 1,
                    "{allowed} writes: a flashed bank after the erase"
                );
                assert_eq!(c.read_bank(0, s.len, |_| {}).unwrap(), old);
                old.clone()
            }
            BankState::Builtin(_) => EMOJI.to_vec(),
            BankState::Refused { .. } => Vec::new(),
        };
        assert!(
            allowed == 1 || dev(&mut c).dev.region()[..8] == [0xFF; 8],
            "the head is written last"
        );
        // Whatever plays is that bank's slot 1, whole: never the new, half-written one.
        if !played.is_empty() {
            let started = c.play(1).unwrap();
            let want = host_codes(&played, 1);
            c.pump(Duration::from_millis(want.len() as u64 + 10))
                .unwrap();
            let frames = dev(&mut c).dev.outputs();
            assert_eq!(
                at(frames, &want, 0),
                Some(started.tick as usize),
                "{allowed} writes"
            );
        } else {
            assert!(c.play(1).is_err());
        }
        // And a whole upload afterwards succeeds.
        c.upload(&new, |_| {}).unwrap();
        c.reconnect().unwrap();
        c.verify(&new, |_| {}).unwrap();
    }
}

#[test]
fn a_commit_with_a_bad_crc_is_refused_and_nothing_plays_from_the_region() {
    let new = hot_bank(30_000_000);
    let mut c = sleeve(EMOJI);
    let wrong = touch_protocol::container::crc32(&new) ^ 1;
    let begin = raw(
        &mut c,
        100,
        Command::BankBegin {
            len: new.len() as u32,
            crc: wrong,
        },
    );
    assert!(
        matches!(begin, Message::Reply { seq: 100, .. }),
        "{begin:?}"
    );
    let mut seq = 101;
    for (i, chunk) in new.chunks(link::MAX_CHUNK).enumerate() {
        let m = raw(
            &mut c,
            seq,
            Command::BankChunk {
                offset: (i * link::MAX_CHUNK) as u32,
                bytes: chunk,
            },
        );
        assert!(matches!(m, Message::Reply { .. }), "{m:?}");
        seq += 1;
    }
    let m = raw(&mut c, seq, Command::BankCommit);
    match m {
        Message::Refused {
            error: LinkError::BadCrc { expected, computed },
            ..
        } => {
            assert_eq!(expected, wrong);
            assert_eq!(computed, wrong ^ 1);
        }
        other => panic!("{other:?}"),
    }
    dev(&mut c).dev.restart();
    c.reconnect().unwrap();
    assert!(
        !matches!(c.info().unwrap().bank, BankState::Flashed(_)),
        "the refused image is not the bank"
    );
}

#[test]
fn an_abandoned_upload_leaves_the_region_erased_and_the_builtin_bank_playing() {
    let old = hot_bank(30_000_000);
    let mut c = sleeve(&old);
    let begin = raw(&mut c, 50, Command::BankBegin { len: 1000, crc: 0 });
    assert!(matches!(begin, Message::Reply { seq: 50, .. }), "{begin:?}");
    // Nothing plays while an upload holds the region.
    assert!(matches!(c.play(0), Err(ClientError::Refused { .. })));
    c.abort_upload().unwrap();
    c.reconnect().unwrap();
    assert!(matches!(c.info().unwrap().bank, BankState::Builtin(_)));
    assert!(dev(&mut c).dev.region().iter().all(|&b| b == 0xFF));
    // An abort without an upload is refused.
    match c.abort_upload() {
        Err(ClientError::Refused {
            error: LinkError::NoUpload,
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn malformed_and_truncated_frames_are_answered_and_the_link_recovers() {
    let mut c = sleeve(EMOJI);
    // Garbage that is not COBS, a frame with a damaged CRC, a frame cut short
    // (its end lost, so the next frame's bytes join it), and a too-long one.
    let mut wire = [0u8; link::MAX_ENCODED];
    let n = link::encode(
        &Request {
            seq: 9,
            command: Command::Info,
        },
        &mut wire,
    )
    .unwrap();
    let mut damaged = wire[..n].to_vec();
    damaged[2] ^= 0x40;
    let answers = raw_bytes(&mut c, &damaged);
    assert!(
        matches!(
            answers.as_slice(),
            [Message::Unreadable(link::FrameError::BadCrc)]
        ),
        "{answers:?}"
    );
    let answers = raw_bytes(&mut c, &[0x05, 0x01, 0x00]);
    assert!(
        matches!(answers.as_slice(), [Message::Unreadable(_)]),
        "{answers:?}"
    );
    let answers = raw_bytes(&mut c, &[0xAA; 600]);
    assert!(answers.is_empty(), "no zero yet: {answers:?}");
    let answers = raw_bytes(&mut c, &[0x00]);
    assert!(
        matches!(
            answers.as_slice(),
            [Message::Unreadable(link::FrameError::TooLong)]
        ),
        "{answers:?}"
    );
    // A good CRC over bytes that are not a request.
    let body = [0x05u8, 0x7F];
    let mut frame = body.to_vec();
    frame.extend_from_slice(&touch_protocol::container::crc32(&body).to_le_bytes());
    let mut stuffed = [0u8; 16];
    let k = link::cobs::encode(&frame, &mut stuffed).unwrap();
    let mut bytes = stuffed[..k].to_vec();
    bytes.push(0);
    let answers = raw_bytes(&mut c, &bytes);
    assert!(
        matches!(
            answers.as_slice(),
            [Message::Unreadable(link::FrameError::Malformed)] | [Message::Refused { .. }]
        ),
        "{answers:?}"
    );
    // A truncated frame (no zero): the client's next request joins it, is lost,
    // and its retry gets through.
    dev(&mut c).dev.write(&wire[..n - 3]);
    assert!(c.info().is_ok());
    assert!(c.status().is_ok());
}

#[test]
fn a_host_that_vanishes_mid_stream_leaves_the_outputs_at_0a() {
    let s = flat("long", 9830, 5000, Limits::SLEEVE);
    let stim = Stimulus::decode(&s).unwrap();
    let mut c = sleeve(EMOJI);
    // Hello and info are in; the stream's begin and a few chunks, then the cable goes.
    dev(&mut c).writes_left = Some(1 + 1 + 6);
    let r = c.stream(&stim, |_| {});
    assert!(matches!(r, Err(ClientError::Io(_))), "{r:?}");
    let d = dev(&mut c);
    let last = d.ms as usize;
    // What the device holds: at most its 32 keyframes of 100 ms.
    let buffered: usize = 32 * 100;
    d.run((buffered + 300) as u64);
    let frames = d.dev.outputs();
    assert!(
        frames[..last].iter().any(|f| f[0] > IDLE_FRAME[0]),
        "the stream played before the host vanished"
    );
    let rest = (last..frames.len())
        .find(|&i| frames[i..].iter().all(|f| *f == IDLE_FRAME))
        .expect("at rest");
    // The buffer plays out (the dead-man counts from it running dry), then the
    // deadline (50 ms without data) at most, then the stream's 40 ms ramp.
    assert!(
        rest - last <= buffered + link::STREAM_DEADLINE_MS as usize + 40 + 2,
        "at 0 A {} ms after the last data",
        rest - last
    );
    // The device said why, to whoever listens.
    let mut why = None;
    while let Some(e) = c.next_event(Duration::ZERO).unwrap() {
        if let Event::StreamStopped(r) = e.event {
            why = Some((e.tick as usize, r));
        }
    }
    let (tick, why) = why.expect("a StreamStopped event");
    assert!(
        matches!(why, StreamStop::Deadline | StreamStop::Underrun),
        "{why:?}"
    );
    assert!(
        tick - last <= buffered + link::STREAM_DEADLINE_MS as usize + 1,
        "stopped {} ms after",
        tick - last
    );
}

#[test]
fn a_stream_plays_through_and_ends() {
    let s = flat("stream", 9830, 600, Limits::SLEEVE);
    let stim = Stimulus::decode(&s).unwrap();
    let mut c = sleeve(EMOJI);
    let mut last = 0;
    c.stream(&stim, |p| last = p.done).unwrap();
    assert_eq!(last, u64::from(stim.header().keyframe_count));
    let mut finished = false;
    while let Some(e) = c.next_event(Duration::from_millis(2000)).unwrap() {
        if e.event == Event::Finished(Source::Stream) {
            finished = true;
            break;
        }
    }
    assert!(finished, "the stream played out");
    c.pump(Duration::from_millis(5)).unwrap();
    let frames = dev(&mut c).dev.outputs();
    assert!(frames.iter().any(|f| f[3] > IDLE_FRAME[3] + 500));
    assert_eq!(*frames.last().unwrap(), IDLE_FRAME);
}

#[test]
fn a_stream_longer_than_the_devices_buffer_is_paced_by_its_room() {
    // 10 ms keyframes for 2 s: far more than the device buffers at once.
    let s = flat_every("long", 9830, 2000, Limits::SLEEVE, 10);
    let stim = Stimulus::decode(&s).unwrap();
    let total = u64::from(stim.header().keyframe_count);
    let mut c = sleeve(EMOJI);
    let mut acked = Vec::new();
    c.stream(&stim, |p| acked.push(p.done)).unwrap();
    assert_eq!(acked.last(), Some(&total));
    let mut stopped = None;
    while let Some(e) = c.next_event(Duration::from_millis(3000)).unwrap() {
        match e.event {
            Event::StreamStopped(r) => stopped = Some(r),
            Event::Finished(Source::Stream) => break,
            _ => {}
        }
    }
    assert_eq!(stopped, Some(StreamStop::Ended), "never starved, never cut");
    let frames = dev(&mut c).dev.outputs();
    let on = frames.iter().filter(|f| f[0] > IDLE_FRAME[0] + 400).count();
    assert!(on >= 1900, "{on} ms at 0.3 A");
}

#[test]
fn a_play_is_refused_while_a_coil_is_too_hot() {
    // A 1 A^2 s budget: slot 0 trips in about 1.5 s and leaves the coils hot.
    let hot = hot_bank(1_000_000);
    let mut c = sleeve(&hot);
    c.play(0).unwrap();
    let mut tripped = false;
    while let Some(e) = c.next_event(Duration::from_millis(3500)).unwrap() {
        if let Event::LimitHit { kind, .. } = e.event {
            assert_eq!(kind, touch_protocol::link::Limit::Thermal);
            tripped = true;
            break;
        }
    }
    assert!(tripped, "slot 0 hit its thermal limit");
    // A play during the ramp down is taken (it starts after the ramp, if the coils
    // allow it then); once at rest, the coils are still near their budget.
    while let Some(e) = c.next_event(Duration::from_millis(200)).unwrap() {
        if e.event == Event::Finished(Source::Slot(0)) {
            break;
        }
    }
    match c.play(1) {
        Err(ClientError::Refused {
            error:
                LinkError::TooHot {
                    permille,
                    cooldown_ms,
                    ..
                },
            ..
        }) => {
            assert!(permille > 500, "{permille}");
            assert!(cooldown_ms > 0);
        }
        other => panic!("{other:?}"),
    }
    assert!(dev(&mut c).dev.outputs().last() == Some(&IDLE_FRAME));
    // The status says why: the thermal trip, and warm coils. (Its heat is per mille
    // of the device's own budget, 30 A^2 s, not of this bank's stricter 1 A^2 s.)
    let st = c.status().unwrap();
    let fault = st.last_fault.expect("the trip is recorded");
    assert_eq!(fault.kind, touch_protocol::link::Limit::Thermal);
    assert!(st.heat_permille.iter().all(|&h| h > 0), "{st:?}");
}

#[test]
fn a_button_press_is_an_event_with_its_tick() {
    let mut c = sleeve(EMOJI);
    dev(&mut c).run(5);
    let d = dev(&mut c);
    d.dev.press(sleeve_firmware::button::Event::Toggle);
    c.pump(Duration::from_millis(20)).unwrap();
    let mut got = Vec::new();
    while let Some(e) = c.next_event(Duration::ZERO).unwrap() {
        got.push(e.event);
    }
    assert!(got.contains(&Event::Started(Source::Slot(0))), "{got:?}");
}
