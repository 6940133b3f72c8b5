//! Recording to the sleeve's outputs: compile the shipped examples with `touchc`,
//! pack them into a bank, boot the firmware's logic on the bank as it would sit in
//! flash, press a button, and check every 1 kHz frame against the protocol player
//! and the compiler's own signal.

use std::cell::Cell;
use std::path::Path;
use std::rc::Rc;

use sleeve_firmware::boot::check_bank;
use sleeve_firmware::button::{Buttons, Mode};
use sleeve_firmware::control::{Controller, Report};
use sleeve_firmware::engine::{Engine, Watchdog};
use sleeve_firmware::output::{device_config, Frame, IDLE_FRAME};
use touch_protocol::player::code_to_amps;
use touch_protocol::{bank, OutputSink, Player, Status, Stimulus};
use touchc_input::recording::Recording;
use touchc_pipeline::compile::{compile, CompileOptions, Compiled};

struct Recorder(Vec<Frame>);

impl OutputSink for Recorder {
    fn write(&mut self, codes: &Frame) {
        self.0.push(*codes);
    }
}

struct Dog(Rc<Cell<u32>>);

impl Watchdog for Dog {
    fn feed(&mut self) {
        self.0.set(self.0.get() + 1);
    }
}

fn compile_example(name: &str) -> Compiled {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(format!("{name}.npy"));
    let rec = Recording::load(&path).unwrap();
    let opts = CompileOptions {
        name: name.into(),
        ..CompileOptions::default()
    };
    compile(&rec, &opts).unwrap()
}

/// The bank as the firmware sees it: at the start of an erased 256 KB flash region.
fn flash_region(image: &[u8]) -> Vec<u8> {
    let mut region = vec![0xFF; 256 * 1024];
    region[..image.len()].copy_from_slice(image);
    region
}

#[test]
fn examples_play_on_the_firmware_exactly_as_compiled() {
    let names = ["stroke", "squeeze", "tap_pat"];
    let compiled: Vec<Compiled> = names.iter().map(|n| compile_example(n)).collect();
    let files: Vec<&[u8]> = compiled.iter().map(|c| c.stimulus.as_slice()).collect();
    let region = flash_region(&bank::encode(&files).unwrap());
    let bank = check_bank(&region).unwrap();
    assert_eq!(bank.len(), 3);

    for (slot, c) in compiled.iter().enumerate() {
        let name = names[slot];
        let feeds = Rc::new(Cell::new(0));
        let controller = Controller::new(bank, device_config());
        let buttons = Buttons::<3>::new(Mode::PerSlot);
        let mut engine = Engine::new(
            Recorder(Vec::new()),
            Dog(feeds.clone()),
            buttons,
            controller,
        );
        let mut reports = Vec::new();
        // Button `slot` goes down at tick 5 and stays down.
        let ticks = 5 + c.signal.len() + 200;
        for t in 0..ticks {
            let mut edges = [None; 3];
            if t == 5 {
                edges[slot] = Some(true);
            }
            engine.tick(edges, |r| reports.push(r), || {});
        }
        assert_eq!(
            reports.first(),
            Some(&Report::Started(slot)),
            "{name}: {reports:?}"
        );
        assert!(
            reports.contains(&Report::Finished(slot)),
            "{name}: {reports:?}"
        );
        assert!(
            !reports.iter().any(|r| matches!(r, Report::Fault(..))),
            "{reports:?}"
        );
        assert_eq!(feeds.get(), ticks as u32, "the watchdog is fed every tick");

        // Frame for frame what the protocol player computes on the host...
        let stimulus = Stimulus::decode(&c.stimulus).unwrap();
        let expected: Vec<Frame> = Player::new(&stimulus, &device_config())
            .take_while(|t| t.status != Status::Finished)
            .map(|t| t.codes)
            .collect();
        let written = &engine.sink().0;
        let start = written.iter().position(|f| *f != IDLE_FRAME).unwrap();
        let first_active = expected.iter().position(|f| *f != IDLE_FRAME).unwrap();
        let begin = start - first_active;
        assert!(written[..begin].iter().all(|f| *f == IDLE_FRAME));
        assert_eq!(
            &written[begin..begin + expected.len()],
            &expected[..],
            "{name}"
        );
        assert!(written[begin + expected.len()..]
            .iter()
            .all(|f| *f == IDLE_FRAME));

        // ...and within the compiler's fidelity bound of its f64 signal.
        let fs = device_config().full_scale_ma;
        let n = c.signal.len();
        let sum2: f64 = (0..n)
            .map(|t| {
                let frame = expected.get(t).copied().unwrap_or(IDLE_FRAME);
                (0..8)
                    .map(|ch| (code_to_amps(frame[ch], fs) - c.signal[t][ch]).powi(2))
                    .sum::<f64>()
            })
            .sum();
        let rms = (sum2 / (8 * n) as f64).sqrt();
        assert!(rms <= 0.005, "{name}: RMS error {rms}");
    }
}

#[test]
fn a_damaged_bank_is_refused() {
    let c = compile_example("stroke");
    let mut image = bank::encode(&[c.stimulus.as_slice()]).unwrap();
    let at = image.len() / 2;
    image[at] ^= 0x01;
    assert!(check_bank(&flash_region(&image)).is_err());
    assert!(check_bank(&[0xFF; 1024]).is_err());
}
