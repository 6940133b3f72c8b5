//! The link server and the controller together, through real frames, on the
//! in-memory sleeve ([`super::sim::Device`]): every command, damaged frames, uploads
//! cut at every chunk, a bad CRC, a refusal by the thermal state, the stream's
//! deadline.

use touch_protocol::link::{
    self, cobs, BankState, Busy, Command, Event, FrameError, LinkError, Message, PlayReply, Reply,
    Request, Source, StopReply, StreamBeginReply, StreamStop,
};
use touch_protocol::{Limits, Stimulus, CHANNELS, IDLE_CODE};

use super::bank::bank_crc;
use super::sim::Device;
use crate::button::Event as Button;
use crate::output::{device_config, Frame, IDLE_FRAME};
use crate::testutil::{bank, constant_stimulus, for_layout, stimulus_from};

/// The host's side, as a test drives it: sends requests, collects frames.
struct Host {
    dev: Device,
    seq: u16,
    rx: cobs::Decoder<{ link::MAX_ENCODED }>,
    /// Unstuffed frames not yet looked at.
    frames: Vec<Vec<u8>>,
    events: Vec<(u32, Event)>,
    unreadable: Vec<FrameError>,
}

impl Host {
    fn new(dev: Device) -> Self {
        Host {
            dev,
            seq: 0,
            rx: cobs::Decoder::new(),
            frames: Vec::new(),
            events: Vec::new(),
            unreadable: Vec::new(),
        }
    }

    fn pump(&mut self) {
        for b in self.dev.read() {
            if let cobs::Feed::Frame(f) = self.rx.feed(b) {
                let f = f.to_vec();
                match link::decode::<Message>(&f).expect("the device sends good frames") {
                    Message::Event { tick, event } => self.events.push((tick, event)),
                    Message::Unreadable(e) => self.unreadable.push(e),
                    _ => self.frames.push(f),
                }
            }
        }
    }

    fn send(&mut self, command: Command<'_>) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        let mut wire = [0u8; link::MAX_ENCODED];
        let n = link::encode(
            &Request {
                seq: self.seq,
                command,
            },
            &mut wire,
        )
        .unwrap();
        self.dev.write(&wire[..n]);
        self.seq
    }

    /// Sends `command` and ticks until its answer: `Ok(reply frame)` or the refusal.
    fn call(&mut self, command: Command<'_>) -> Result<Vec<u8>, LinkError> {
        let seq = self.send(command);
        for _ in 0..10 {
            self.pump();
            if let Some(i) = self.frames.iter().position(|f| {
                matches!(link::decode::<Message>(f), Ok(Message::Reply { seq: s, .. } | Message::Refused { seq: s, .. }) if s == seq)
            }) {
                let f = self.frames.remove(i);
                return match link::decode::<Message>(&f).unwrap() {
                    Message::Refused { error, .. } => Err(error),
                    _ => Ok(f),
                };
            }
            self.dev.tick();
        }
        panic!("no answer to {command:?}")
    }

    fn run(&mut self, ms: usize) {
        for _ in 0..ms {
            self.dev.tick();
        }
        self.pump();
    }
}

fn reply(frame: &[u8]) -> Reply<'_> {
    match link::decode::<Message>(frame).unwrap() {
        Message::Reply { reply, .. } => reply,
        m => panic!("not a reply: {m:?}"),
    }
}

fn two_slots() -> Vec<u8> {
    bank(&[
        constant_stimulus("a", 300, 400),
        constant_stimulus("b", -300, 400),
    ])
}

fn builtin() -> Vec<u8> {
    bank(&[constant_stimulus("builtin", 100, 100)])
}

fn host() -> Host {
    Host::new(Device::boot(&two_slots(), &builtin()))
}

#[test]
fn hello_info_and_slots() {
    let mut h = host();
    let f = h
        .call(Command::Hello {
            version: link::VERSION,
        })
        .unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Hello {
            version: link::VERSION,
            ..
        }
    ));
    assert_eq!(
        h.call(Command::Hello { version: 99 }),
        Err(LinkError::UnsupportedVersion {
            device: link::VERSION
        })
    );
    let f = h.call(Command::Info).unwrap();
    let Reply::Info(info) = reply(&f) else {
        panic!()
    };
    let image = two_slots();
    assert_eq!(
        info.bank,
        BankState::Flashed(link::BankSummary {
            len: image.len() as u32,
            crc: host_bank_crc(&image),
            slots: 2
        })
    );
    assert_eq!(info.limits, device_config().limits);
    assert_eq!(
        (info.layout, info.layout_hash),
        (
            touch_protocol::layout::SLEEVE_NAME,
            touch_protocol::layout::SLEEVE_HASH
        )
    );
    assert_eq!(info.max_chunk as usize, link::MAX_CHUNK);
    let f = h.call(Command::Slot { slot: 1 }).unwrap();
    let Reply::Slot(s) = reply(&f) else { panic!() };
    assert_eq!((s.name, s.playable), ("b", true));
    assert_eq!(s.playback_ms, s.duration_ms + 40);
    assert_eq!(
        h.call(Command::Slot { slot: 2 }),
        Err(LinkError::NoSuchSlot { slot: 2, slots: 2 })
    );
    // Bank reads: the region's bytes, shorter at its end, refused past it.
    let f = h.call(Command::BankRead { offset: 0, len: 16 }).unwrap();
    assert_eq!(
        reply(&f),
        Reply::BankData {
            offset: 0,
            bytes: &image[..16]
        }
    );
    let end = touch_protocol::bank::REGION_LEN as u32;
    let f = h
        .call(Command::BankRead {
            offset: end - 3,
            len: 16,
        })
        .unwrap();
    assert!(matches!(reply(&f), Reply::BankData { bytes, .. } if bytes.len() == 3));
    assert_eq!(
        h.call(Command::BankRead {
            offset: 0,
            len: 257
        }),
        Err(LinkError::Malformed),
        "SPEC: a length over 256 breaks the command's rule"
    );
    assert_eq!(
        h.call(Command::BankRead {
            offset: end + 1,
            len: 16
        }),
        Err(LinkError::OutOfRange)
    );
}

/// The CRC a bank carries at its end, over every byte before it, as the host computes
/// it from the file.
fn host_bank_crc(image: &[u8]) -> u32 {
    touch_protocol::container::crc32(&image[..image.len() - 4])
}

#[test]
fn info_gives_each_bank_its_own_crc() {
    // A bank's CRC covers its stimuli's own CRCs, so two banks of one slot whose
    // stimuli have the same length share it (each stimulus is a CRC codeword): this
    // one's name makes it a byte longer than the built-in's.
    let other = bank(&[constant_stimulus("other", 500, 700)]);
    let mut crcs = Vec::new();
    // Two flashed banks, and the built-in one (the region erased).
    for (image, flashed) in [(two_slots(), true), (other, true), (builtin(), false)] {
        let mut h = if flashed {
            Host::new(Device::boot(&image, &builtin()))
        } else {
            Host::new(Device::boot(&[], &image))
        };
        let f = h.call(Command::Info).unwrap();
        let Reply::Info(info) = reply(&f) else {
            panic!()
        };
        let (BankState::Flashed(s) | BankState::Builtin(s)) = info.bank else {
            panic!("{:?}", info.bank)
        };
        assert_eq!(s.crc, host_bank_crc(&image), "{:?}", info.bank);
        crcs.push(s.crc);
    }
    assert!(
        crcs[0] != crcs[1] && crcs[1] != crcs[2] && crcs[0] != crcs[2],
        "{crcs:x?}"
    );
}

#[test]
fn an_erased_region_reports_the_builtin_bank_and_a_bad_one_its_led_code() {
    let mut h = Host::new(Device::boot(&[], &builtin()));
    let f = h.call(Command::Info).unwrap();
    let Reply::Info(info) = reply(&f) else {
        panic!()
    };
    assert!(matches!(info.bank, BankState::Builtin(s) if s.slots == 1));
    let mut bad = two_slots();
    bad[40] ^= 1;
    let mut h = Host::new(Device::boot(&bad, &builtin()));
    let f = h.call(Command::Info).unwrap();
    let Reply::Info(info) = reply(&f) else {
        panic!()
    };
    assert_eq!(info.bank, BankState::Refused { blinks: 4 });
    assert_eq!(
        h.call(Command::Play { slot: 0 }),
        Err(LinkError::NoSuchSlot { slot: 0, slots: 0 })
    );
    assert_eq!(h.call(Command::Slot { slot: 0 }), Err(LinkError::NoBank));
}

/// A `Play` waiting for the tick is taken by it, and that tick writes the slot's
/// first frame itself, not the next one: a request that just missed a tick is on
/// the outputs at the following one (the link's 2 ms wherever it lands).
#[test]
fn a_play_is_on_the_outputs_in_the_tick_that_takes_it() {
    let mut h = host();
    h.run(5);
    h.send(Command::Play { slot: 1 });
    let next = h.dev.outputs().len();
    h.run(10);
    let first = h.dev.outputs().iter().position(|f| *f != IDLE_FRAME);
    assert_eq!(first, Some(next), "the slot's first frame in the next tick");
    assert!(h
        .events
        .contains(&(next as u32, Event::Started(Source::Slot(1)))));
}

#[test]
fn play_answers_the_tick_of_the_first_frame_and_stop_the_ramp() {
    let mut h = host();
    h.run(5);
    let f = h.call(Command::Play { slot: 1 }).unwrap();
    let Reply::Play(PlayReply {
        slot: 1,
        tick,
        now: true,
    }) = reply(&f)
    else {
        panic!("{:?}", reply(&f))
    };
    h.run(100);
    let out = h.dev.outputs();
    assert_eq!(out[tick as usize - 1], IDLE_FRAME);
    assert_ne!(
        out[tick as usize], IDLE_FRAME,
        "first frame at the answered tick"
    );
    assert!(h.events.contains(&(tick, Event::Started(Source::Slot(1)))));
    let f = h.call(Command::Status).unwrap();
    let Reply::Status(st) = reply(&f) else {
        panic!()
    };
    assert_eq!(
        (st.playing, st.selected, st.stopping),
        (Some(Source::Slot(1)), 1, false)
    );
    let f = h.call(Command::Stop).unwrap();
    let Reply::Stop(StopReply {
        source: Some(Source::Slot(1)),
        tick: stop,
    }) = reply(&f)
    else {
        panic!()
    };
    h.run(200);
    let out = h.dev.outputs();
    assert!(out[stop as usize]
        .iter()
        .zip(&out[stop as usize - 1])
        .all(|(a, b)| a.abs_diff(IDLE_CODE) <= b.abs_diff(IDLE_CODE)));
    assert_eq!(*out.last().unwrap(), IDLE_FRAME);
    assert!(h
        .events
        .iter()
        .any(|e| e.1 == Event::Finished(Source::Slot(1))));
    // Stop with nothing playing: answered, nothing to stop.
    let f = h.call(Command::Stop).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Stop(StopReply { source: None, .. })
    ));
    assert_eq!(
        h.call(Command::Play { slot: 7 }),
        Err(LinkError::NoSuchSlot { slot: 7, slots: 2 })
    );
}

#[test]
fn play_over_a_playing_slot_ramps_it_down_first() {
    let mut h = host();
    h.call(Command::Play { slot: 0 }).unwrap();
    h.run(50);
    let f = h.call(Command::Play { slot: 1 }).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Play(PlayReply {
            slot: 1,
            now: false,
            ..
        })
    ));
    h.run(300);
    let started: Vec<_> = h
        .events
        .iter()
        .filter(|e| matches!(e.1, Event::Started(_)))
        .collect();
    assert_eq!(started.len(), 2, "{:?}", h.events);
    assert_eq!(started[1].1, Event::Started(Source::Slot(1)));
    assert_ne!(h.dev.outputs()[started[1].0 as usize], IDLE_FRAME);
    assert_eq!(h.dev.outputs()[started[1].0 as usize - 1], IDLE_FRAME);
}

#[test]
fn button_gestures_are_events_with_their_tick() {
    let mut h = host();
    h.run(10);
    h.dev.press(Button::Toggle);
    h.run(10);
    assert_eq!(h.events[0], (10, Event::Button(link::Gesture::Toggle)));
    assert_eq!(h.events[1], (11, Event::Started(Source::Slot(0))));
    assert_ne!(h.dev.outputs()[11], IDLE_FRAME);
}

#[test]
fn a_hot_coil_refuses_a_play_as_it_refuses_a_press() {
    let hot = stimulus_from("hot", 1000, &vec![[32767; CHANNELS]; 61], Limits::SLEEVE);
    let mut h = Host::new(Device::boot(&bank(&[hot]), &builtin()));
    h.call(Command::Play { slot: 0 }).unwrap();
    h.run(60_000);
    assert!(h.events.iter().any(|e| matches!(
        e.1,
        Event::LimitHit {
            kind: link::Limit::Thermal,
            ..
        }
    )));
    let refusal = h.call(Command::Play { slot: 0 });
    let Err(LinkError::TooHot {
        permille,
        cooldown_ms,
        ..
    }) = refusal
    else {
        panic!("{refusal:?}")
    };
    assert!(permille > 500 && cooldown_ms > 0);
    let f = h.call(Command::Status).unwrap();
    let Reply::Status(st) = reply(&f) else {
        panic!()
    };
    assert!(
        st.heat_permille.iter().all(|&p| p > 500) && st.cooldown_ms > 0 && st.faults == 1,
        "{st:?}"
    );
    assert_eq!(st.last_fault.map(|f| f.kind), Some(link::Limit::Thermal));
    // The button is refused the same.
    assert!(matches!(
        h.dev.press(Button::Toggle),
        Some(crate::control::Report::TooHot(0, _))
    ));
}

/// A slot with a stricter I^2 t budget than the device's: what `Status` says of the
/// heat is what a start of the selected slot is judged by, so it agrees with the
/// refusal of a `Play` of that slot, per mille and cooldown.
#[test]
fn status_and_a_too_hot_refusal_judge_the_heat_by_the_same_budget() {
    let strict = Limits {
        i2t_budget_ma2s: 1_000_000,
        ..Limits::SLEEVE
    };
    let bold = stimulus_from("bold", 1000, &[[32767; CHANNELS]; 4], Limits::SLEEVE);
    let careful = stimulus_from("careful", 1000, &[[8000; CHANNELS]; 4], strict);
    let mut h = Host::new(Device::boot(&bank(&[careful, bold]), &builtin()));
    // Two seconds at 1 A heat every coil to about 1.3 A^2 s: 43 per mille of the
    // device's 30 A^2 s, more than the careful slot's whole 1 A^2 s.
    h.call(Command::Play { slot: 1 }).unwrap();
    h.run(2000);
    h.call(Command::Stop).unwrap();
    h.run(100);
    // Select the careful slot again (a long press moves the selection on).
    h.dev.press(Button::Next);
    h.run(2);
    let f = h.call(Command::Status).unwrap();
    let Reply::Status(st) = reply(&f) else {
        panic!()
    };
    assert_eq!(st.selected, 0);
    let refusal = h.call(Command::Play { slot: 0 });
    let Err(LinkError::TooHot {
        channel,
        permille,
        cooldown_ms,
    }) = refusal
    else {
        panic!("{refusal:?}")
    };
    assert!(permille > 500, "{permille}");
    // A few milliseconds of cooling apart.
    let said = st.heat_permille[usize::from(channel)];
    assert!(
        said.abs_diff(permille) <= 2,
        "status {said}, refusal {permille} per mille"
    );
    assert!(
        st.cooldown_ms.abs_diff(cooldown_ms) <= 10,
        "status {} ms, refusal {cooldown_ms} ms",
        st.cooldown_ms
    );
}

/// The two places for players: the link stages one, replaces it with another slot's,
/// keeps it when asked for the same slot again; the tick takes only the slot it
/// starts, swapping places (the player is not copied), and the link's next one goes
/// to the other place, leaving the one that plays alone.
#[test]
fn the_tick_takes_the_staged_player_and_the_link_builds_in_the_other_place() {
    use super::Channels;
    use touch_protocol::{Player, Thermal};
    let image = two_slots();
    let bank = touch_protocol::Bank::decode(&image).unwrap();
    let device = device_config();
    let build = |slot: u8| {
        let s = bank.slot(usize::from(slot)).ok()?;
        Some(Player::with_thermal(&s, &device, Thermal::COLD))
    };
    let channels: &mut Channels = Box::leak(Box::new(Channels::new()));
    let (mut link, mut tick) = channels.split();
    let warm = Thermal::from_heat_ma2ms([3_000_000_000; CHANNELS]);
    assert_eq!((link.staged(), link.wanted()), (None, None));
    assert!(!tick.take_player(0, &warm));
    link.stage(0, || build(0));
    assert_eq!((link.staged(), link.wanted()), (Some(0), Some(0)));
    link.stage(1, || build(1));
    assert_eq!((link.staged(), link.wanted()), (Some(1), Some(1)));
    link.stage(1, || panic!("slot 1 is staged already"));
    assert!(!tick.take_player(0, &warm));
    assert!(tick.take_player(1, &warm));
    assert_eq!(link.staged(), None);
    // Built in the other place: the taken player plays on, slot 1 from the warm coil.
    link.stage(0, || build(0));
    assert_eq!(link.staged(), Some(0));
    let s = bank.slot(1).unwrap();
    let mut want = Player::with_thermal(&s, &device, warm);
    for _ in 0..50 {
        assert_eq!(tick.player().tick(), want.tick());
    }
    tick.want(1);
    assert_eq!(link.wanted(), Some(1));
}

/// A `Play` whose player is not staged (a press took the place, or asked for
/// another slot) stays in the queue: the tick asks the link for it, and once it is
/// staged the `Play` starts and is answered with the tick of its first frame.
#[test]
fn a_play_waits_for_its_player() {
    use super::{Answer, Channels, Control, LinkPort};
    use crate::control::Controller;
    use touch_protocol::link::TickReply;
    use touch_protocol::{Player, Thermal};

    fn run(
        c: &mut Controller<'_>,
        port: &mut LinkPort<'_, '_>,
        frames: &mut Vec<crate::output::Frame>,
        answers: &mut Vec<Answer>,
        n: usize,
    ) {
        for _ in 0..n {
            // As the engine writes them: a slot a command started goes out in the
            // tick that started it, over what that tick wrote first.
            let mut first = None;
            c.send_later(&mut |_| {});
            let frame = c.tick_with(|_| {}, |f| first = Some(*f));
            if let Some(first) = first {
                *frames.last_mut().expect("a tick before the play") = first;
            }
            frames.push(frame);
            while let Some(a) = port.receive() {
                answers.push(a);
            }
        }
    }

    let image = two_slots();
    let bank = touch_protocol::Bank::decode(&image).unwrap();
    let mut c = Controller::new(bank, device_config());
    let channels: &mut Channels = Box::leak(Box::new(Channels::new()));
    let (mut port, tick) = channels.split();
    c.attach(tick);
    let (mut frames, mut answers) = (Vec::new(), Vec::new());
    run(&mut c, &mut port, &mut frames, &mut answers, 3);
    port.send(Control::Play { seq: 7, slot: 1 }).unwrap();
    run(&mut c, &mut port, &mut frames, &mut answers, 5);
    assert_eq!(port.wanted(), Some(1), "the tick asks for slot 1's player");
    assert!(answers.is_empty(), "{answers:?}");
    assert!(frames.iter().all(|f| *f == IDLE_FRAME));
    let s = bank.slot(1).unwrap();
    port.stage(1, || {
        Some(Player::with_thermal(&s, &device_config(), Thermal::COLD))
    });
    run(&mut c, &mut port, &mut frames, &mut answers, 5);
    let reply = answers.iter().find_map(|a| match a {
        Answer::Reply(
            7,
            TickReply::Play(PlayReply {
                slot: 1,
                tick,
                now: true,
            }),
        ) => Some(*tick),
        _ => None,
    });
    let Some(tick) = reply else {
        panic!("{answers:?}")
    };
    // The frame computed at tick n (frames[n]) goes out at tick n + 1: the answer
    // names that tick.
    assert_eq!(frames[tick as usize - 2], IDLE_FRAME);
    assert_ne!(frames[tick as usize - 1], IDLE_FRAME);
    assert_eq!(c.playing(), Some(1));
}

/// The players the link's task builds ahead and hands to the tick play exactly what
/// the controller alone plays when it builds each player itself, warm coils, trips
/// and refusals included: the press schedule below, on the in-memory sleeve and on
/// a bare controller, gives the same frames and the same reports, tick for tick.
#[test]
fn players_built_ahead_play_as_players_built_in_the_tick() {
    use crate::control::Report;
    let limits = Limits {
        i2t_budget_ma2s: 2_000_000,
        ..Limits::SLEEVE
    };
    let hot = stimulus_from("hot", 500, &[[32767; CHANNELS]; 9], limits);
    let other = stimulus_from("other", 100, &[[-20000; CHANNELS]; 9], Limits::SLEEVE);
    let image = bank(&[hot, other]);
    let mut dev = Device::boot(&image, &builtin());
    let b = touch_protocol::Bank::decode(&image).unwrap();
    let mut bare = crate::control::Controller::new(b, device_config());
    let mut bare_frames = vec![IDLE_FRAME];
    let (mut bare_reports, mut presses) = (Vec::new(), Vec::new());
    let ticks = 120_000;
    for t in 0..ticks {
        // A press every 2.5 s (a trip, a refusal, a stop, a start), a long press
        // (the next slot) every 23 s.
        let press = match t {
            _ if t % 23_000 == 50 => Some(Button::Next),
            _ if t % 2500 == 10 => Some(Button::Toggle),
            _ => None,
        };
        if let Some(p) = press {
            let r = dev.press(p);
            assert_eq!(r, bare.handle(p), "tick {t}: the press's report");
            presses.extend(r);
        }
        dev.tick();
        let (frame, report) = bare.next_frame();
        bare_frames.push(frame);
        if let Some(r) = report {
            bare_reports.push((t as u32, r));
        }
    }
    let frames = dev.outputs();
    assert_eq!(frames.len(), ticks);
    for t in 0..ticks {
        assert_eq!(frames[t], bare_frames[t], "tick {t}");
    }
    assert_eq!(dev.reports(), &bare_reports[..]);
    let trips = bare_reports
        .iter()
        .filter(|(_, r)| matches!(r, Report::Fault(..)))
        .count();
    let refused = presses
        .iter()
        .filter(|r| matches!(r, Report::TooHot(..)))
        .count();
    let starts = presses
        .iter()
        .filter(|r| matches!(r, Report::Started(1)))
        .count();
    assert!(
        trips > 2 && refused > 2 && starts > 0,
        "{trips} trips, {refused} refusals, {starts} starts of slot 1"
    );
}

/// A `Status` that would land on a tick whose player decodes its next keyframe (the
/// dearest ticks) is answered a tick later; on any other tick, at once.
#[test]
fn a_status_is_not_answered_on_a_keyframe_tick() {
    let period = 20u32;
    let frames: Vec<[i16; CHANNELS]> = (0..50).map(|i| [(i * 300) as i16; CHANNELS]).collect();
    let s = stimulus_from("ramps", period as u16, &frames, Limits::SLEEVE);
    let mut h = Host::new(Device::boot(&bank(&[s]), &builtin()));
    h.run(5);
    let f = h.call(Command::Play { slot: 0 }).unwrap();
    let Reply::Play(PlayReply { tick: first, .. }) = reply(&f) else {
        panic!()
    };
    // The tick that started it computed its first frame.
    let start = first - 1;
    let mut late = 0;
    for _ in 0..3 * period {
        let sent = h.dev.controller().now();
        let f = h.call(Command::Status).unwrap();
        let Reply::Status(st) = reply(&f) else {
            panic!()
        };
        assert_ne!(
            st.tick.wrapping_sub(start) % period,
            period - 1,
            "answered on a keyframe tick"
        );
        late += usize::from(st.tick > sent);
    }
    assert!(late > 0 && late < 10, "{late} answered a tick late");
}

#[test]
fn damaged_frames_are_answered_unreadable_and_the_next_one_works() {
    let mut h = host();
    // Garbage (not COBS), a frame too long, a CRC error, a truncated frame, a good
    // CRC over a request that does not decode.
    h.dev.write(&[0x05, 0x01, 0x00]);
    h.dev.write(&[0x11; 400]);
    h.dev.write(&[0x00]);
    let mut wire = [0u8; link::MAX_ENCODED];
    let n = link::encode(
        &Request {
            seq: 9,
            command: Command::Info,
        },
        &mut wire,
    )
    .unwrap();
    let mut bad = wire[..n].to_vec();
    bad[2] ^= 0x10;
    h.dev.write(&bad);
    h.dev.write(&wire[..3]);
    h.dev.write(&[0x00]);
    h.dev.write(&[0x03, 0x01, 0x02, 0x00]);
    let body = [0x01, 0x63];
    let mut raw = body.to_vec();
    raw.extend_from_slice(&bank_crc(&body).to_le_bytes());
    let mut stuffed = [0u8; 16];
    let m = cobs::encode(&raw, &mut stuffed).unwrap();
    h.dev.write(&stuffed[..m]);
    h.dev.write(&[0x00]);
    // `Info` (seq 7) with three bytes after it, under a good CRC (postcard alone
    // would stop at the message's end and answer it).
    let body = [0x07, 0x01, 0x00, 0x00, 0x00];
    let mut raw = body.to_vec();
    raw.extend_from_slice(&bank_crc(&body).to_le_bytes());
    let m = cobs::encode(&raw, &mut stuffed).unwrap();
    h.dev.write(&stuffed[..m]);
    h.dev.write(&[0x00]);
    h.pump();
    assert_eq!(
        h.unreadable,
        [
            FrameError::Cobs,
            FrameError::TooLong,
            FrameError::BadCrc,
            FrameError::Cobs,
            FrameError::Short,
            FrameError::Malformed,
            FrameError::Malformed
        ]
    );
    assert!(
        h.frames.is_empty(),
        "the request with trailing bytes was answered"
    );
    assert!(h.call(Command::Info).is_ok());
    // A chunk longer than MAX_CHUNK is refused (it still fits a frame).
    h.call(Command::BankBegin { len: 1000, crc: 0 }).unwrap();
    assert_eq!(
        h.call(Command::BankChunk {
            offset: 0,
            bytes: &[1; 257]
        }),
        Err(LinkError::Malformed)
    );
}

#[test]
fn a_pipelined_flood_gets_one_answer_per_request_and_a_full_queue_its_own() {
    let mut h = host();
    h.call(Command::Play { slot: 0 }).unwrap();
    let seqs: Vec<u16> = (0..40).map(|_| h.send(Command::Status)).collect();
    h.run(60);
    let mut answers = std::collections::BTreeMap::<u16, Vec<Result<(), LinkError>>>::new();
    for f in h.frames.drain(..) {
        match link::decode::<Message>(&f).unwrap() {
            Message::Reply { seq, reply } => {
                assert!(matches!(reply, Reply::Status(_)), "{reply:?}");
                answers.entry(seq).or_default().push(Ok(()));
            }
            Message::Refused { seq, error } => answers.entry(seq).or_default().push(Err(error)),
            m => panic!("{m:?}"),
        }
    }
    assert!(h.unreadable.is_empty());
    for seq in &seqs {
        let a = answers.get(seq).map_or(&[][..], |a| &a[..]);
        assert_eq!(a.len(), 1, "request {seq}: {a:?}");
        assert!(matches!(a[0], Ok(()) | Err(LinkError::QueueFull)), "{a:?}");
    }
    let full = answers.values().filter(|a| a[0].is_err()).count();
    assert!(
        full > 0 && full < seqs.len(),
        "{full} of {} refused",
        seqs.len()
    );
}

/// Uploads `image` in chunks of `chunk` through the link; the reply to the commit.
fn upload(h: &mut Host, image: &[u8], chunk: usize) -> Result<Vec<u8>, LinkError> {
    h.call(Command::BankBegin {
        len: image.len() as u32,
        crc: bank_crc(image),
    })?;
    for (i, c) in image.chunks(chunk).enumerate() {
        let f = h.call(Command::BankChunk {
            offset: (i * chunk) as u32,
            bytes: c,
        })?;
        assert_eq!(
            reply(&f),
            Reply::BankChunk {
                next: (i * chunk + c.len()) as u32
            }
        );
    }
    h.call(Command::BankCommit)
}

#[test]
fn an_upload_commits_and_the_device_restarts_into_it() {
    let mut h = host();
    let new = bank(&[
        constant_stimulus("x", 200, 300),
        constant_stimulus("y", 200, 300),
        constant_stimulus("z", 200, 300),
    ]);
    let f = upload(&mut h, &new, link::MAX_CHUNK).unwrap();
    assert_eq!(
        reply(&f),
        Reply::BankCommit {
            crc: bank_crc(&new),
            slots: 3
        }
    );
    h.run(1);
    assert_eq!(h.dev.boots, 1);
    let f = h.call(Command::Info).unwrap();
    let Reply::Info(info) = reply(&f) else {
        panic!()
    };
    assert!(
        matches!(info.bank, BankState::Flashed(s) if s.crc == host_bank_crc(&new) && s.slots == 3)
    );
    let f = h.call(Command::Slot { slot: 2 }).unwrap();
    assert!(matches!(reply(&f), Reply::Slot(s) if s.name == "z"));
    let f = h.call(Command::Play { slot: 2 }).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Play(PlayReply {
            slot: 2,
            now: true,
            ..
        })
    ));
}

#[test]
fn uploads_wait_for_rest_and_lock_the_bank() {
    let mut h = host();
    h.call(Command::Play { slot: 0 }).unwrap();
    assert_eq!(
        h.call(Command::BankBegin { len: 100, crc: 0 }),
        Err(LinkError::Busy(Busy::Playing))
    );
    h.run(600);
    h.call(Command::BankBegin { len: 100, crc: 0 }).unwrap();
    assert_eq!(
        h.call(Command::Play { slot: 0 }),
        Err(LinkError::Busy(Busy::Uploading))
    );
    assert_eq!(
        h.call(Command::Slot { slot: 0 }),
        Err(LinkError::Busy(Busy::Uploading))
    );
    // A press does not start a slot of the erased bank either.
    h.dev.press(Button::Toggle);
    h.run(100);
    assert!(h.dev.outputs()[h.dev.outputs().len() - 100..]
        .iter()
        .all(|f| *f == IDLE_FRAME));
    let f = h.call(Command::Status).unwrap();
    assert!(matches!(reply(&f), Reply::Status(s) if s.upload == Some(0)));
    // Abandoned: the device restarts into the built-in bank.
    h.call(Command::BankAbort).unwrap();
    h.run(1);
    let f = h.call(Command::Info).unwrap();
    assert!(matches!(reply(&f), Reply::Info(i) if matches!(i.bank, BankState::Builtin(_))));
    assert_eq!(h.call(Command::BankCommit), Err(LinkError::NoUpload));
}

#[test]
fn a_bank_for_another_layout_is_refused_at_commit_and_never_boots() {
    let s = constant_stimulus("mirrored", 200, 100);
    let other = bank(&[for_layout(
        &s,
        touch_protocol::layout::SLEEVE_HASH.rotate_left(8),
    )]);
    let mut h = host();
    assert_eq!(
        upload(&mut h, &other, 64),
        Err(LinkError::WrongLayout { slot: 0 })
    );
    h.dev.restart();
    let f = h.call(Command::Info).unwrap();
    assert!(matches!(reply(&f), Reply::Info(i) if matches!(i.bank, BankState::Builtin(_))));
}

#[test]
fn a_bad_crc_commit_is_refused_and_a_new_upload_can_follow() {
    let mut h = host();
    let new = two_slots();
    h.call(Command::BankBegin {
        len: new.len() as u32,
        crc: bank_crc(&new) ^ 0xFF,
    })
    .unwrap();
    let half = new.len() / 2;
    h.call(Command::BankChunk {
        offset: 0,
        bytes: &new[..half],
    })
    .unwrap();
    h.call(Command::BankChunk {
        offset: half as u32,
        bytes: &new[half..],
    })
    .unwrap();
    assert_eq!(
        h.call(Command::BankCommit),
        Err(LinkError::BadCrc {
            expected: bank_crc(&new) ^ 0xFF,
            computed: bank_crc(&new)
        })
    );
    assert!(upload(&mut h, &new, 100).is_ok());
}

/// The host vanishes after every chunk of an upload and the power is cycled: the
/// device boots the built-in bank, plays it on a press, and answers a new upload.
#[test]
fn an_upload_cut_at_every_chunk_leaves_the_builtin_bank() {
    let new = bank(&[
        constant_stimulus("x", 200, 2000),
        constant_stimulus("y", 200, 2000),
    ]);
    let chunks = new.len().div_ceil(16);
    assert!(chunks > 8, "{chunks}");
    for cut in 0..chunks {
        let mut h = host();
        h.call(Command::BankBegin {
            len: new.len() as u32,
            crc: bank_crc(&new),
        })
        .unwrap();
        for (i, c) in new.chunks(16).take(cut).enumerate() {
            h.call(Command::BankChunk {
                offset: (i * 16) as u32,
                bytes: c,
            })
            .unwrap();
        }
        h.dev.restart();
        let f = h.call(Command::Info).unwrap();
        assert!(
            matches!(reply(&f), Reply::Info(i) if matches!(i.bank, BankState::Builtin(_))),
            "cut after chunk {cut}"
        );
        let f = h.call(Command::Play { slot: 0 }).unwrap();
        assert!(matches!(
            reply(&f),
            Reply::Play(PlayReply { now: true, .. })
        ));
    }
}

/// The host stops in the middle of an upload and never comes back (killed): 10 s
/// after its last upload request (not before, and counted again from each chunk),
/// the device drops the staged upload and restarts into the built-in bank, which
/// plays. Another program's requests meanwhile (`Info`, a refused `Play`) do not
/// keep the upload alive.
#[test]
fn an_upload_abandoned_for_10_s_restarts_into_the_builtin_bank() {
    use super::server::UPLOAD_IDLE_MS;
    assert_eq!(UPLOAD_IDLE_MS, 10_000);
    let new = bank(&[constant_stimulus("x", 200, 2000)]);
    let mut h = host();
    h.call(Command::BankBegin {
        len: new.len() as u32,
        crc: bank_crc(&new),
    })
    .unwrap();
    let chunks: Vec<_> = new.chunks(16).collect();
    h.call(Command::BankChunk {
        offset: 0,
        bytes: chunks[0],
    })
    .unwrap();
    // A chunk 8 s later starts the wait again.
    h.run(8_000);
    assert_eq!(h.dev.boots, 0);
    h.call(Command::BankChunk {
        offset: 16,
        bytes: chunks[1],
    })
    .unwrap();
    let last_chunk = h.dev.ms;
    // Another program tries the sleeve every second meanwhile: refused, busy.
    for _ in 0..9 {
        h.run(1000);
        assert_eq!(h.dev.boots, 0, "restarted before 10 s of silence");
        assert_eq!(
            h.call(Command::Play { slot: 0 }),
            Err(LinkError::Busy(Busy::Uploading))
        );
        assert!(h.call(Command::Info).is_ok());
    }
    while h.dev.boots == 0 && h.dev.ms < last_chunk + 20_000 {
        h.dev.tick();
    }
    assert_eq!(
        h.dev.boots, 1,
        "no restart 20 s after the upload went silent"
    );
    let silent = h.dev.ms - last_chunk;
    assert!(
        (10_000..=10_010).contains(&silent),
        "restarted after {silent} ms"
    );
    let f = h.call(Command::Info).unwrap();
    assert!(matches!(reply(&f), Reply::Info(i) if matches!(i.bank, BankState::Builtin(_))));
    assert_eq!(h.call(Command::BankCommit), Err(LinkError::NoUpload));
    let f = h.call(Command::Play { slot: 0 }).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Play(PlayReply { now: true, .. })
    ));
}

/// `BankAbort` (what `touchc sleeve abort` sends) ends a stale upload at once: the
/// device restarts into the built-in bank, which plays.
#[test]
fn an_abort_ends_a_stale_upload_into_the_builtin_bank() {
    let new = bank(&[constant_stimulus("x", 200, 2000)]);
    let mut h = host();
    h.call(Command::BankBegin {
        len: new.len() as u32,
        crc: bank_crc(&new),
    })
    .unwrap();
    h.call(Command::BankChunk {
        offset: 0,
        bytes: &new[..16],
    })
    .unwrap();
    h.run(1000);
    assert!(h.call(Command::BankAbort).is_ok());
    h.run(5);
    assert_eq!(h.dev.boots, 1);
    let f = h.call(Command::Info).unwrap();
    assert!(matches!(reply(&f), Reply::Info(i) if matches!(i.bank, BankState::Builtin(_))));
    let f = h.call(Command::Play { slot: 0 }).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Play(PlayReply { now: true, .. })
    ));
    // Nothing left to abort.
    assert_eq!(h.call(Command::BankAbort), Err(LinkError::NoUpload));
}

fn stream_params() -> link::StreamParams {
    link::StreamParams {
        keyframe_period_ms: 20,
        ramp_ms: 20,
        full_scale_ma: 1000,
        limits: Limits::SLEEVE,
    }
}

fn stream_keyframes(n: usize) -> Vec<[i16; 8]> {
    (0..n)
        .map(|i| core::array::from_fn(|c| ((i * 700 + c * 900) % 16000) as i16 - 8000))
        .collect()
}

/// Sends keyframes `from..to` in chunks of up to 8.
fn feed(h: &mut Host, ks: &[[i16; 8]], from: usize, to: usize) {
    let mut at = from;
    while at < to {
        let n = (to - at).min(8);
        let mut bytes = [0u8; 8 * link::KEYFRAME_LEN];
        let len = link::put_stream_keyframes(&ks[at..at + n], &mut bytes);
        let f = h
            .call(Command::StreamData {
                index: at as u32,
                keyframes: &bytes[..len],
            })
            .unwrap();
        assert!(matches!(reply(&f), Reply::StreamData { next, .. } if next as usize == at + n));
        at += n;
    }
}

/// The codes the stored player gives for a stimulus of the stream's keyframes.
fn stored_codes(ks: &[[i16; 8]]) -> Vec<[u16; 8]> {
    let file = touch_protocol::stimulus::Builder::new("s", 20)
        .ramp_ms(20)
        .layout("test", 1)
        .encode(ks)
        .unwrap();
    let stored = Stimulus::decode(&file).unwrap();
    touch_protocol::Player::new(&stored, &device_config())
        .take(stored.duration_ms() as usize)
        .map(|t| t.codes)
        .collect()
}

/// Streams `ks` (20 ms keyframes), the first 16 at once, then waits `gap(sent)`
/// ms and tops the buffer up (as far as its room allows, as the host does), until
/// every keyframe is sent; returns the host and the stream's first frame.
fn stream_with_gaps(ks: &[[i16; 8]], mut gap: impl FnMut(usize) -> usize) -> (Host, usize) {
    let mut h = host();
    let f = h.call(Command::StreamBegin(stream_params())).unwrap();
    let Reply::StreamBegin(StreamBeginReply { capacity }) = reply(&f) else {
        panic!()
    };
    assert_eq!(capacity, 32);
    feed(&mut h, ks, 0, 16);
    let mut sent = 16;
    while sent < ks.len() {
        h.run(gap(sent));
        loop {
            let n = (ks.len() - sent).min(8);
            let mut bytes = [0u8; 8 * link::KEYFRAME_LEN];
            let len = link::put_stream_keyframes(&ks[sent..sent + n], &mut bytes);
            match h.call(Command::StreamData {
                index: sent as u32,
                keyframes: &bytes[..len],
            }) {
                Ok(_) => sent += n,
                Err(LinkError::StreamFull { .. }) => break,
                Err(e) => panic!("keyframe {sent}: {e:?}"),
            }
            if sent == ks.len() {
                break;
            }
        }
    }
    h.call(Command::StreamEnd).unwrap();
    h.run(1000);
    let started = h
        .events
        .iter()
        .find(|e| e.1 == Event::Started(Source::Stream))
        .unwrap()
        .0 as usize;
    (h, started)
}

#[test]
fn a_stream_plays_like_the_stimulus_of_its_keyframes() {
    let ks = stream_keyframes(30);
    // Every 40 ms (2 keyframes): inside the deadline.
    let (h, started) = stream_with_gaps(&ks, |_| 40);
    assert!(
        h.events
            .iter()
            .any(|e| e.1 == Event::StreamStopped(StreamStop::Ended)),
        "{:?}",
        h.events
    );
    assert!(h
        .events
        .iter()
        .any(|e| e.1 == Event::Finished(Source::Stream)));
    // The stored player, on a stimulus of the same keyframes: the same codes.
    let expected = stored_codes(&ks);
    assert_eq!(
        &h.dev.outputs()[started..started + expected.len()],
        &expected[..]
    );
    assert_eq!(*h.dev.outputs().last().unwrap(), IDLE_FRAME);
}

/// A host that stalls for longer than the deadline while the buffer still holds
/// keyframes (up to 32 of 20 ms: 640 ms ahead) does not cut the stimulus: the dead-man
/// counts from the buffer running dry, not from the last data.
#[test]
fn a_host_that_stalls_within_the_buffer_never_cuts_the_stimulus() {
    let ks = stream_keyframes(60);
    // 40 ms between top-ups, but 200 ms (four deadlines) at two points.
    let (h, started) =
        stream_with_gaps(&ks, |sent| if sent == 20 || sent == 40 { 200 } else { 40 });
    let stops: Vec<Event> = h
        .events
        .iter()
        .map(|e| e.1)
        .filter(|e| matches!(e, Event::StreamStopped(_)))
        .collect();
    assert_eq!(
        stops,
        [Event::StreamStopped(StreamStop::Ended)],
        "{:?}",
        h.events
    );
    let expected = stored_codes(&ks);
    assert_eq!(
        &h.dev.outputs()[started..started + expected.len()],
        &expected[..]
    );
}

#[test]
fn a_host_that_vanishes_mid_stream_brings_the_outputs_to_rest() {
    let ks = stream_keyframes(30);
    let mut h = host();
    h.call(Command::StreamBegin(stream_params())).unwrap();
    feed(&mut h, &ks, 0, 30);
    // Nothing more: no data, no end.
    h.run(1000);
    let started = h
        .events
        .iter()
        .find(|e| e.1 == Event::Started(Source::Stream))
        .unwrap()
        .0;
    // The last keyframe sent is due 29 periods after the first frame: the buffer
    // plays out, then the outputs ramp to 0 A within the deadline and the ramp.
    let last_keyframe = started + 29 * 20;
    let (tick, why) = *h
        .events
        .iter()
        .find(|e| matches!(e.1, Event::StreamStopped(_)))
        .expect("the stream stopped");
    assert!(
        matches!(
            why,
            Event::StreamStopped(StreamStop::Deadline | StreamStop::Underrun)
        ),
        "{why:?}"
    );
    assert!(
        tick <= last_keyframe + link::STREAM_DEADLINE_MS,
        "{tick} vs {last_keyframe}"
    );
    let rest = h
        .dev
        .outputs()
        .iter()
        .rposition(|f| *f != IDLE_FRAME)
        .unwrap() as u32
        + 1;
    assert!(
        rest <= last_keyframe + link::STREAM_DEADLINE_MS + 20 + 20,
        "at rest {} ms after the last keyframe",
        rest - last_keyframe
    );
    // Every keyframe sent was played before the ramp.
    let expected = stored_codes(&ks);
    let n = (last_keyframe - started) as usize;
    assert_eq!(
        &h.dev.outputs()[started as usize..started as usize + n],
        &expected[..n]
    );
    // Data after the stream stopped is refused.
    let mut bytes = [0u8; 16];
    link::put_stream_keyframes(&ks[..1], &mut bytes);
    assert_eq!(
        h.call(Command::StreamData {
            index: 30,
            keyframes: &bytes
        }),
        Err(LinkError::NoStream)
    );
}

/// A host that sends a stream's first keyframe and vanishes: the armed stream
/// is forgotten at its start deadline (one keyframe never starts it).
#[test]
fn an_armed_stream_without_its_second_keyframe_ends_at_the_deadline() {
    let ks = stream_keyframes(1);
    let mut h = host();
    h.call(Command::StreamBegin(stream_params())).unwrap();
    feed(&mut h, &ks, 0, 1);
    let last_data = h.dev.controller().now();
    h.run(link::STREAM_START_MS as usize + 200);
    let (tick, _) = *h
        .events
        .iter()
        .find(|e| e.1 == Event::StreamStopped(StreamStop::Deadline))
        .expect("the deadline forgot the stream");
    assert!(tick - last_data >= link::STREAM_START_MS - 1);
    assert!(tick - last_data <= link::STREAM_START_MS + 1);
    assert!(h.dev.outputs().iter().all(|f| *f == IDLE_FRAME));
}

#[test]
fn stream_rules() {
    let ks = stream_keyframes(40);
    let mut h = host();
    let mut bytes = [0u8; 16];
    link::put_stream_keyframes(&ks[..1], &mut bytes);
    assert_eq!(
        h.call(Command::StreamData {
            index: 0,
            keyframes: &bytes
        }),
        Err(LinkError::NoStream)
    );
    assert_eq!(h.call(Command::StreamEnd), Err(LinkError::NoStream));
    let mut bad = stream_params();
    bad.keyframe_period_ms = 0;
    assert_eq!(h.call(Command::StreamBegin(bad)), Err(LinkError::Malformed));
    h.call(Command::StreamBegin(stream_params())).unwrap();
    assert_eq!(
        h.call(Command::StreamData {
            index: 0,
            keyframes: &bytes[..15]
        }),
        Err(LinkError::Malformed)
    );
    assert_eq!(
        h.call(Command::StreamData {
            index: 3,
            keyframes: &bytes
        }),
        Err(LinkError::StreamGap { expected: 0 })
    );
    feed(&mut h, &ks, 0, 32);
    assert_eq!(
        h.call(Command::Play { slot: 0 }),
        Err(LinkError::Busy(Busy::Streaming))
    );
    // The buffer holds 32: 16 more do not fit (the player took 2 or 3 so far).
    let mut sixteen = [0u8; link::MAX_CHUNK];
    link::put_stream_keyframes(&ks[..16], &mut sixteen);
    let r = h.call(Command::StreamData {
        index: 32,
        keyframes: &sixteen,
    });
    assert!(matches!(r, Err(LinkError::StreamFull { .. })), "{r:?}");
    let f = h.call(Command::Stop).unwrap();
    assert!(matches!(
        reply(&f),
        Reply::Stop(StopReply {
            source: Some(Source::Stream),
            ..
        })
    ));
    h.run(200);
    assert_eq!(*h.dev.outputs().last().unwrap(), IDLE_FRAME);
    assert!(h.call(Command::Play { slot: 0 }).is_ok());
}

/// The tick's side alone: a stream begun, then fed one keyframe per period, plays
/// on without an underrun when the host keeps two keyframes ahead (the live player
/// needs the keyframe after next at each boundary), and stops when only one.
#[test]
fn a_stream_fed_ahead_plays_on() {
    use super::{Answer, Channels, Control};
    use crate::control::Controller;
    let image = two_slots();
    let run = |ahead: usize| {
        let bank = touch_protocol::Bank::decode(&image).unwrap();
        let mut c = Controller::new(bank, device_config());
        let channels: &mut Channels = Box::leak(Box::new(Channels::new()));
        let (mut port, tick) = channels.split();
        c.attach(tick);
        let mut events = Vec::new();
        port.send(Control::StreamBegin {
            seq: 1,
            params: stream_params(),
        })
        .unwrap();
        c.next_frame();
        for t in 1..2000u32 {
            if t % 20 == 1 {
                let v = (((t / 20) % 20) as i16).min(10) * 2000;
                let n = if t == 1 { 1 + ahead } else { 1 };
                for _ in 0..n {
                    port.push_keyframe([v; 8]).unwrap();
                }
                port.fed();
            }
            c.next_frame();
            while let Some(a) = port.receive() {
                if let Answer::Event(_, e) = a {
                    events.push(e);
                }
            }
        }
        (c.streaming(), events)
    };
    let (on, events) = run(2);
    assert!(on, "{events:?}");
    let (on, events) = run(1);
    assert!(
        !on && events.contains(&Event::StreamStopped(StreamStop::Underrun)),
        "{events:?}"
    );
}

/// Streams `ks` whole on `h` (data, end, played out); the outputs from its
/// `Started` event on.
fn stream_all(h: &mut Host, ks: &[[i16; 8]]) -> Vec<Frame> {
    h.call(Command::StreamBegin(stream_params())).unwrap();
    let since = h.events.len();
    feed(h, ks, 0, ks.len());
    h.call(Command::StreamEnd).unwrap();
    h.run(ks.len() * 20 + 200);
    let (started, _) = h.events[since..]
        .iter()
        .find(|e| e.1 == Event::Started(Source::Stream))
        .copied()
        .expect("the stream started");
    h.dev.outputs()[started as usize..].to_vec()
}

#[test]
fn a_stream_plays_its_own_keyframes_after_one_stopped_before_it_started() {
    let level = |q: i16| vec![[q; 8]; 6];
    let alone = stream_all(&mut host(), &level(-6000));
    // A first stream stopped after its first two keyframes came and before the
    // tick started it: the player the link built from them is left staged.
    let mut h = host();
    h.call(Command::StreamBegin(stream_params())).unwrap();
    let mut bytes = [0u8; 2 * link::KEYFRAME_LEN];
    let len = link::put_stream_keyframes(&level(9000)[..2], &mut bytes);
    h.send(Command::StreamData {
        index: 0,
        keyframes: &bytes[..len],
    });
    h.send(Command::Stop);
    h.run(100);
    assert!(!h
        .events
        .iter()
        .any(|e| e.1 == Event::Started(Source::Stream)));
    let after = stream_all(&mut h, &level(-6000));
    let n = alone.len().min(after.len());
    let parts = (0..n).find(|&i| after[i] != alone[i]);
    assert_eq!(
        parts, None,
        "the second stream parts from the same one alone"
    );
}
