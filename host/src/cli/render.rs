//! `touchc render FILE --csv | --wav out.wav`: the player's 1 kHz output, from the same
//! code the firmware runs, as CSV or as an 8-channel WAV for an audio interface.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use touch_protocol::DeviceConfig;
use touchc::output::write_atomic;
use touchc::viz::{play, wav, Playback};

/// Arguments of `touchc render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A `.touch` stimulus, or a `.bank` with `--slot`.
    file: PathBuf,
    /// Write CSV: `t_s,ch0,...,ch7`, currents in amperes, one row per 1 kHz tick.
    #[arg(long)]
    csv: bool,
    /// Where to write the CSV (default: standard output).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write an 8-channel WAV here: 16-bit PCM, full scale = the device's full scale,
    /// channels in sleeve order, linearly interpolated between the 1 kHz ticks.
    #[arg(long)]
    wav: Option<PathBuf>,
    /// The WAV's sample rate, Hz (1000 ..= 768000).
    #[arg(long, default_value_t = 48_000, requires = "wav")]
    rate: u32,
    /// Which slot of a bank to render.
    #[arg(long, default_value_t = 0)]
    slot: usize,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !args.csv && args.wav.is_none() {
        bail!("choose an output: --csv and/or --wav FILE");
    }
    if args.output.is_some() && !args.csv {
        bail!("-o names the CSV output: add --csv (the WAV goes to --wav FILE)");
    }
    let bytes = super::read_input(&args.file)?;
    let stimulus = super::stimulus_in(&bytes, &args.file, args.slot)?;
    let playback = play(&stimulus, &DeviceConfig::default());
    if let Some((t, f)) = playback.fault {
        eprintln!(
            "touchc: warning: {:?} limit hit on channel {} at {:.3} s; the player ramped to 0 A",
            f.kind,
            f.channel,
            t as f64 / 1000.0
        );
    }
    if let Some(path) = &args.wav {
        let audio = wav::encode(&playback.codes, args.rate)
            .with_context(|| format!("{}: cannot write a WAV", path.display()))?;
        write_atomic(path, &audio)?;
    }
    if args.csv {
        let csv = render_csv(&playback);
        match &args.output {
            Some(path) => write_atomic(path, csv.as_bytes())?,
            None => print!("{csv}"),
        }
    }
    Ok(())
}

/// One CSV row per tick until the player finishes.
fn render_csv(playback: &Playback) -> String {
    let mut out = String::from("t_s,ch0,ch1,ch2,ch3,ch4,ch5,ch6,ch7\n");
    for (t, codes) in playback.codes.iter().enumerate() {
        let _ = write!(out, "{:.3}", t as f64 / 1000.0);
        for ch in 0..codes.len() {
            let _ = write!(out, ",{:.6}", playback.amps(t, ch));
        }
        out.push('\n');
    }
    out
}
