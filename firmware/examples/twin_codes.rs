//! The host player's codes for one bank slot, for the firmware twin
//! (`firmware/twin/`) to compare the emulated binary's compare registers against.
//!
//! - `twin_codes play BANK SLOT [STOP_AFTER]` prints one line per 1 kHz tick: the
//!   eight codes and the player's status (`P` playing, `R` ramping down, `F` fault,
//!   `E` finished), from the first tick to the finished one. With `STOP_AFTER`, the
//!   player is asked to stop after that many ticks, as a press during playback does.
//!   The device is the firmware's own (`output::device_config`).
//! - `twin_codes limit BANK SLOT PEAK_MA OUT` writes a one-slot bank: that slot
//!   re-encoded with its peak limit lowered to `PEAK_MA`, so that it trips.
use std::io::Write;
use std::process::ExitCode;

use sleeve_firmware::output::device_config;
use touch_protocol::player::Status;
use touch_protocol::{bank, stimulus, Bank, Player};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("twin_codes: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &[String]) -> Result<(), String> {
    let usage = "usage: twin_codes play BANK SLOT [STOP_AFTER] | limit BANK SLOT PEAK_MA OUT";
    let [command, path, slot, rest @ ..] = args else {
        return Err(usage.into());
    };
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    let bank = Bank::decode(&bytes).map_err(|e| format!("{path}: {e:?}"))?;
    let slot: usize = number(slot)?;
    let stimulus = bank
        .slot(slot)
        .map_err(|e| format!("{path}: slot {slot}: {e:?}"))?;
    match (command.as_str(), rest) {
        ("play", []) => play(&stimulus, None),
        ("play", [n]) => play(&stimulus, Some(number(n)?)),
        ("limit", [peak, out]) => {
            let mut header = *stimulus.header();
            header.limits.peak_ma = number(peak)?;
            let frames: Vec<_> = stimulus.keyframes().collect();
            let one = stimulus::encode(header, &frames).map_err(|e| format!("{e:?}"))?;
            let image = bank::encode(&[&one]).map_err(|e| format!("{e:?}"))?;
            std::fs::write(out, image).map_err(|e| format!("{out}: {e}"))
        }
        _ => Err(usage.into()),
    }
}

fn number<T: std::str::FromStr>(s: &str) -> Result<T, String>
where
    T::Err: std::fmt::Display,
{
    s.parse().map_err(|e| format!("{s}: {e}"))
}

fn play(stimulus: &touch_protocol::Stimulus<'_>, stop_after: Option<u64>) -> Result<(), String> {
    let mut player = Player::new(stimulus, &device_config());
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    for tick in 0u64.. {
        if Some(tick) == stop_after {
            player.stop();
        }
        let t = player.tick();
        let status = match t.status {
            Status::Playing => 'P',
            Status::RampingDown => 'R',
            Status::Fault(_) => 'F',
            Status::Finished => 'E',
        };
        let codes: Vec<String> = t.codes.iter().map(u16::to_string).collect();
        writeln!(out, "{} {status}", codes.join(" ")).map_err(|e| e.to_string())?;
        if status == 'E' {
            break;
        }
    }
    out.flush().map_err(|e| e.to_string())
}
