//! Makes the test bank with the protocol crate's encoder, plays every slot with the
//! host's player, and writes the bank and the expected tick counts and code hashes
//! for the target to check against. Links with the workspace's
//! `memory.x`, as the firmware does.

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::{env, fs};

use sleeve_firmware::button::{Buttons, Mode};
use sleeve_firmware::control::Controller;
use sleeve_firmware::engine::{Engine, Watchdog};
use sleeve_firmware::output::{device_config, Frame};
use sleeve_firmware::testutil;
use sleeve_qemu_shared::{crc32, scenario};
use touch_protocol::player::{DeviceConfig, Player, Status};
use touch_protocol::{bank, stimulus, Bank, Limits, OutputSink, CHANNELS};

/// Keeps the last frame the engine wrote.
struct Last(Frame);
impl OutputSink for Last {
    fn write(&mut self, codes: &Frame) {
        self.0 = *codes;
    }
}
struct NoDog;
impl Watchdog for NoDog {
    fn feed(&mut self) {}
}

/// The firmware's engine through the button scenario: CRC-32 of every frame written.
fn engine_crc(bank: Bank<'_>) -> u32 {
    let controller = Controller::new(bank, device_config());
    let mut engine = Engine::new(
        Last([0; CHANNELS]),
        NoDog,
        Buttons::<1>::new(Mode::PlayNext),
        controller,
    );
    let mut crc = !0u32;
    for t in 0..scenario::TICKS {
        engine.tick([scenario::edge(t)], |_| {}, || {});
        crc = crc32::update_frame(crc, &engine.sink().0);
    }
    !crc
}

/// Q15 of `ma` at `full_scale_ma`.
fn q15(ma: f64, full_scale_ma: u16) -> i16 {
    (ma / f64::from(full_scale_ma) * 32767.0)
        .round()
        .clamp(-32768.0, 32767.0) as i16
}

fn encode(
    name: &str,
    period_ms: u16,
    full_scale_ma: u16,
    limits: Limits,
    frames: Vec<[i16; CHANNELS]>,
) -> Vec<u8> {
    stimulus::Builder::new(name, period_ms)
        .ramp_ms(50)
        .full_scale_ma(full_scale_ma)
        .quant_shift(4)
        .limits(limits)
        .encode(&frames)
        .expect("test stimulus encodes")
}

/// Like the paper's signals: coils rest pre-indented at -0.9 A and a touch moves
/// along the rows towards +1 A, low-passed (keyframes at 40 Hz).
fn stroke() -> Vec<u8> {
    let frames = (0..=100)
        .map(|k| {
            let t = f64::from(k) * 0.025;
            core::array::from_fn(|c| {
                let col = (c % 4) as f64;
                let centre = 0.3 + 0.35 * col + 0.1 * (c / 4) as f64;
                let bump = (-((t - centre) / 0.25).powi(2)).exp();
                q15(-900.0 + 1850.0 * bump, 1000)
            })
        })
        .collect();
    encode("stroke", 25, 1000, Limits::SLEEVE, frames)
}

/// 8 Hz taps of 0.5 A, phase-shifted per channel.
fn tap() -> Vec<u8> {
    let frames = (0..=150)
        .map(|k| {
            let t = f64::from(k) * 0.01;
            core::array::from_fn(|c| q15(500.0 * (2.0 * PI * 8.0 * t + c as f64 * 0.7).sin(), 1000))
        })
        .collect();
    encode("tap", 10, 1000, Limits::SLEEVE, frames)
}

/// Compiled for a bolder device (2 A full scale, 2 A peak): asks 1.3 A, so the
/// device limit stops it with a fault and a ramp down.
fn bold() -> Vec<u8> {
    let loose = Limits {
        peak_ma: 2000,
        slew_ma_per_ms: 100,
        continuous_ma: 1500,
        i2t_budget_ma2s: 100_000_000,
    };
    let frames = (0..=40)
        .map(|k| {
            let ma = (f64::from(k) * 50.0).min(1300.0);
            core::array::from_fn(|c| q15(if c % 2 == 0 { ma } else { -ma }, 2000))
        })
        .collect();
    encode("bold", 40, 2000, loose, frames)
}

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let firmware = manifest
        .join("..")
        .canonicalize()
        .expect("the firmware crate");
    // The workspace root holds the one memory.x.
    let root = firmware.join("..");
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rerun-if-changed={}", root.join("memory.x").display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../../protocol/src");

    // The boot check's worst case: a whole region of two-byte records.
    let dense = testutil::dense_bank(touch_protocol::bank::REGION_LEN);
    fs::write(out.join("dense.bin"), &dense).expect("write dense bank");

    let stimuli = [stroke(), tap(), bold()];
    let refs: Vec<&[u8]> = stimuli.iter().map(Vec::as_slice).collect();
    let image = bank::encode(&refs).expect("test bank encodes");
    fs::write(out.join("bank.bin"), &image).expect("write bank");

    let bank = Bank::decode(&image).expect("bank decodes");
    let device = DeviceConfig::default();
    let mut rs = String::from("/// Per slot: (ticks until Finished, CRC-32 of all codes, faulted).\npub const EXPECTED: &[(u32, u32, bool)] = &[\n");
    for slot in 0..bank.len() {
        let stim = bank.slot(slot).expect("slot decodes");
        let mut player = Player::new(&stim, &device);
        let (mut ticks, mut crc, mut faulted) = (0u32, !0u32, false);
        loop {
            let tick = player.tick();
            ticks += 1;
            crc = crc32::update_frame(crc, &tick.codes);
            faulted |= matches!(tick.status, Status::Fault(_));
            if tick.status == Status::Finished || ticks > 1_000_000 {
                break;
            }
        }
        writeln!(rs, "    ({ticks}, {:#010x}, {faulted}),", !crc).expect("write to string");
    }
    rs.push_str("];\n");
    writeln!(rs, "/// CRC-32 of the frames the engine writes through the button scenario.\npub const ENGINE_CRC: u32 = {:#010x};", engine_crc(bank)).expect("write to string");
    fs::write(out.join("expected.rs"), rs).expect("write expected");
}
