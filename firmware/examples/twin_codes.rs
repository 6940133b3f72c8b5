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
//! - `twin_codes device` prints the firmware's device: full scale (mA) and slew limit
//!   (mA per ms), the numbers the twin derives its bound on the code steps from.
//! - `twin_codes hot BUDGET_MA2S OUT` writes a bank that heats the coils: slot 0
//!   holds near-1 A on most channels for [`HOT_MS`], slot 1 the same for
//!   [`SHORT_MS`]; both carry the sleeve's limits with the I^2 t budget lowered to
//!   `BUDGET_MA2S` (the stricter of stimulus and device wins), so that a few seconds
//!   of play use it up.
//! - `twin_codes big BYTES OUT` writes a one-slot bank of at least `BYTES` bytes:
//!   1 ms keyframes of small pseudo-random currents (they do not compress), for the
//!   twin's upload timing.
use std::io::Write;
use std::process::ExitCode;

use sleeve_firmware::output::{device_config, FULL_SCALE_MA, LAYOUT_HASH};
use touch_protocol::player::Status;
use touch_protocol::{bank, stimulus, Bank, Limits, Player, CHANNELS};

/// Slot 0 of the `hot` bank: longer than a cold coil can carry at the lowered budget.
const HOT_MS: u32 = 3000;
/// Slot 1 of the `hot` bank: short enough to end before it trips.
const SHORT_MS: u32 = 400;
/// The `hot` bank's level per channel, Q15 of full scale: near 1 A of both signs,
/// one channel at 0.5 A (below the 0.6 A rating: it never heats) and one at rest.
const HOT_LEVELS: [i16; CHANNELS] = [32767, -32768, 32112, -31785, 31129, 16384, 0, 32440];

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
    let usage = "usage: twin_codes play BANK SLOT [STOP_AFTER] | limit BANK SLOT PEAK_MA OUT \
                 | hot BUDGET_MA2S OUT | big BYTES OUT | device";
    if let [command] = args {
        if command == "device" {
            let d = device_config();
            println!("{} {}", d.full_scale_ma, d.limits.slew_ma_per_ms);
            return Ok(());
        }
    }
    if let [command, budget, out] = args {
        if command == "hot" {
            return hot(number(budget)?, out);
        }
        if command == "big" {
            return big(number(budget)?, out);
        }
    }
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
            let limits = Limits {
                peak_ma: number(peak)?,
                ..stimulus.limits()
            };
            let frames: Vec<_> = stimulus.keyframes().collect();
            let one = stimulus::Builder::like(stimulus.header())
                .limits(limits)
                .encode(&frames)
                .map_err(|e| format!("{e:?}"))?;
            let image = bank::encode(&[&one]).map_err(|e| format!("{e:?}"))?;
            std::fs::write(out, image).map_err(|e| format!("{out}: {e}"))
        }
        _ => Err(usage.into()),
    }
}

/// Writes the `hot` bank (see the module doc) to `out`.
fn hot(budget_ma2s: u32, out: &str) -> Result<(), String> {
    let limits = Limits {
        i2t_budget_ma2s: budget_ma2s,
        ..Limits::SLEEVE
    };
    // Keyframes every 100 ms, flat: the player's ramp in and out shapes the ends.
    let period_ms = 100u16;
    let one = |name: &str, ms: u32| {
        let frames = vec![HOT_LEVELS; (ms / u32::from(period_ms)) as usize + 1];
        stimulus::Builder::new(name, period_ms)
            .ramp_ms(40)
            .full_scale_ma(FULL_SCALE_MA)
            .layout(touch_protocol::layout::SLEEVE_NAME, LAYOUT_HASH)
            .limits(limits)
            .encode(&frames)
            .map_err(|e| format!("{name}: {e:?}"))
    };
    let (long, short) = (one("hot", HOT_MS)?, one("short", SHORT_MS)?);
    let image = bank::encode(&[&long, &short]).map_err(|e| format!("{e:?}"))?;
    std::fs::write(out, image).map_err(|e| format!("{out}: {e}"))
}

/// Writes a one-slot bank of at least `bytes` bytes (see the module doc) to `out`.
fn big(bytes: usize, out: &str) -> Result<(), String> {
    // A linear congruential generator: the same bank on every machine.
    let mut seed = 0x2545_f491_u32;
    let mut next = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        ((seed >> 16) as i16 >> 5) / 2
    };
    let mut frames = Vec::new();
    loop {
        for _ in 0..50 {
            frames.push([(); CHANNELS].map(|_| next()));
        }
        let one = stimulus::Builder::new("big", 1)
            .ramp_ms(40)
            .full_scale_ma(FULL_SCALE_MA)
            .layout(touch_protocol::layout::SLEEVE_NAME, LAYOUT_HASH)
            .limits(Limits::SLEEVE)
            .encode(&frames)
            .map_err(|e| format!("big: {e:?}"))?;
        let image = bank::encode(&[&one]).map_err(|e| format!("{e:?}"))?;
        if image.len() >= bytes {
            return std::fs::write(out, image).map_err(|e| format!("{out}: {e}"));
        }
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
