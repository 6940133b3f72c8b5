//! `touchc render FILE --csv | --wav out.wav`: the player's 1 kHz output, from the same
//! code the firmware runs, as CSV or as an 8-channel WAV for an audio interface.
//! Both are streamed tick by tick, so a stimulus of any length renders in constant
//! memory, and `touchc render x.touch --csv | head` stops as soon as `head` has enough.

use std::io::Write;
use std::path::PathBuf;

use crate::cli::output::Output;
use anyhow::Context;
use touch_protocol::{DeviceConfig, Stimulus};
use touchc::viz::{describe_fault, play, wav, Ticks};

/// Arguments of `touchc render`.
#[derive(Debug, clap::Args)]
#[command(group = clap::ArgGroup::new("format").required(true).multiple(true).args(["csv", "wav"]))]
pub struct Args {
    /// A `.touch` stimulus, or a `.bank` with `--slot` (`-`: standard input).
    file: PathBuf,
    /// Write CSV: `t_s,ch0,...,ch7`, currents in amperes, one row per 1 kHz tick.
    #[arg(long)]
    csv: bool,
    /// Where to write the CSV (default and `-`: standard output).
    #[arg(short, long, requires = "csv")]
    output: Option<PathBuf>,
    /// Write an 8-channel WAV here (`-`: standard output): 16-bit PCM, full scale = the
    /// device's full scale, channels in sleeve order, linearly interpolated between the
    /// 1 kHz ticks.
    #[arg(long)]
    wav: Option<PathBuf>,
    /// The WAV's sample rate, Hz (1000 ..= 768000).
    #[arg(long, default_value_t = 48_000, requires = "wav")]
    rate: u32,
    /// Which slot of a bank to render.
    /// 0 when not given.
    #[arg(long)]
    slot: Option<usize>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let csv_out = args.csv.then(|| args.output.clone().unwrap_or("-".into()));
    if let (Some(csv), Some(wav)) = (&csv_out, &args.wav) {
        if crate::cli::output::is_stdio(csv) && crate::cli::output::is_stdio(wav) {
            return Err(super::report::usage(
                "the CSV and the WAV cannot both go to standard output: give -o FILE or --wav FILE",
            ));
        }
    }
    {
        use crate::cli::output::{named, refuse_overwrites};
        let mut outputs = Vec::new();
        outputs.extend(csv_out.as_deref().map(|p| named("-o", p)));
        outputs.extend(args.wav.as_deref().map(|p| named("--wav", p)));
        refuse_overwrites(&[named("the stimulus", &args.file)], &outputs)?;
    }
    if let Some(path) = &args.wav {
        let (min, max) = wav::RATE_HZ;
        if !(min..=max).contains(&args.rate) {
            return Err(super::report::usage(format!(
                "--wav {}: --rate {} Hz is out of range: must be {min} to {max} Hz",
                crate::cli::output::shown(path),
                args.rate
            )));
        }
    }
    let bytes = super::input::read_input(&args.file)?;
    let stimulus = super::input::stimulus_in(&bytes, &args.file, args.slot)?;
    super::input::warn_if_unplayable(&args.file, &stimulus);
    let device = DeviceConfig::default();
    let mut fault = None;
    if let Some(path) = &args.wav {
        fault = write_wav(&stimulus, &device, path, args.rate)
            .with_context(|| format!("{}: cannot write a WAV", crate::cli::output::shown(path)))?;
    }
    if let Some(path) = &csv_out {
        let mut out = Output::create(path)?;
        let mut ticks = play(&stimulus, &device);
        write_csv(&mut out, &mut ticks)?;
        out.finish()?;
        fault = ticks.fault();
    }
    if let Some(f) = fault {
        super::report::warn(&args.file, &describe_fault(f));
    }
    Ok(())
}

/// Plays the stimulus twice: once to count its ticks (a WAV's header gives its length
/// first; the count stops where no WAV could hold more), then to write the samples.
fn write_wav(
    stimulus: &Stimulus<'_>,
    device: &DeviceConfig,
    path: &std::path::Path,
    rate: u32,
) -> anyhow::Result<Option<(usize, touch_protocol::player::Fault)>> {
    let most = wav::max_ticks(rate);
    let ticks = play(stimulus, device).take(most.saturating_add(1)).count();
    if ticks > most {
        // Counting stopped at the limit: the header says how long the whole stimulus is.
        let playback = u64::from(stimulus.header().playback_ms()) + 1;
        let ms = usize::try_from(playback).unwrap_or(usize::MAX);
        anyhow::bail!(
            "the stimulus plays {:.1} s, {} sample frames at {rate} Hz, but a WAV holds at \
             most {} frames (4 GiB), {:.1} s at this rate: use a lower --rate",
            playback as f64 / 1000.0,
            wav::frames_for(ms, rate),
            wav::frames_for(most, rate),
            most as f64 / 1000.0,
        );
    }
    let wav = wav::Wav::new(ticks, rate)?;
    let mut out = Output::create(path)?;
    let mut ticks = play(stimulus, device);
    wav.write(&mut out, &mut ticks)?;
    out.finish()?;
    Ok(ticks.fault())
}

/// One CSV row per tick until the player finishes.
fn write_csv(out: &mut impl Write, ticks: &mut Ticks<'_>) -> std::io::Result<()> {
    writeln!(out, "t_s,ch0,ch1,ch2,ch3,ch4,ch5,ch6,ch7")?;
    let mut t = 0u64;
    while let Some(codes) = ticks.next() {
        write!(out, "{:.3}", t as f64 / 1000.0)?;
        for code in codes {
            write!(out, ",{:.6}", ticks.amps(code))?;
        }
        writeln!(out)?;
        t += 1;
    }
    Ok(())
}
