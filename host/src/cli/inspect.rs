//! `touchc inspect FILE`: what is in a stimulus or bank file, and whether it is intact.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use serde::Serialize;
use touch_protocol::{bank, stimulus, Bank, Error, Stimulus};

/// Arguments of `touchc inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A `.touch` stimulus or a `.bank` image (`-`: standard input).
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Where to write (`-`: standard output).
    #[arg(short, long, default_value = "-")]
    output: PathBuf,
}

/// What `inspect` reports: one stimulus, or a bank of them.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum Report {
    Stimulus(StimulusReport),
    Bank(BankReport),
}

/// A bank image and its slots.
#[derive(Debug, Serialize)]
struct BankReport {
    /// Always `bank`.
    kind: &'static str,
    version: u16,
    bytes: usize,
    crc: &'static str,
    /// Geometry hash of the layout every slot was compiled for, hex.
    layout_hash: String,
    slots: Vec<StimulusReport>,
}

/// One stimulus's header and figures; `name` comes from the file (escaped in text).
#[derive(Debug, Serialize)]
struct StimulusReport {
    /// Always `stimulus`.
    kind: &'static str,
    name: String,
    version: u16,
    channels: u8,
    output_rate_hz: u16,
    keyframe_period_ms: u16,
    keyframe_rate_hz: f64,
    keyframes: u32,
    duration_s: f64,
    ramp_ms: u16,
    full_scale_ma: u16,
    resolution_ma: f64,
    /// The layout's name as the file gives it (escaped in text).
    layout: String,
    /// Geometry hash of the layout, hex: what a sleeve compares.
    layout_hash: String,
    limits: Limits,
    bytes: usize,
    /// `None` (JSON null, text `-`) for an empty stimulus.
    bytes_per_second: Option<f64>,
    crc: String,
}

/// The safety limits in the header.
#[derive(Debug, Serialize)]
struct Limits {
    peak_ma: u16,
    slew_ma_per_ms: u16,
    continuous_ma: u16,
    i2t_budget_ma2s: u32,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    use crate::cli::output::{named, refuse_overwrites};
    refuse_overwrites(
        &[named("the file", &args.file)],
        &[named("-o", &args.output)],
    )?;
    let bytes = super::input::read_input(&args.file)?;
    let name = super::input::input_name(&args.file);
    let report = if bytes.starts_with(&bank::MAGIC) {
        let bank = Bank::decode(&bytes).with_context(|| format!("{name}: not a valid bank"))?;
        Report::Bank(BankReport {
            kind: "bank",
            version: bank::VERSION,
            bytes: bank.as_bytes().len(),
            crc: "ok",
            layout_hash: format!("{:#010x}", bank.layout_hash()),
            slots: bank.stimuli().map(|s| stimulus_report(&s)).collect(),
        })
    } else {
        match Stimulus::decode(&bytes) {
            Ok(s) => Report::Stimulus(stimulus_report(&s)),
            Err(e @ Error::BadCrc { .. }) => bail!("{name}: CRC check failed: {e}"),
            Err(e) => {
                return Err(anyhow::Error::new(e).context(format!("{name}: not a valid stimulus")))
            }
        }
    };
    let mut out = crate::cli::output::Output::create(&args.output)?;
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        write_text(&mut out, &report)?;
    }
    out.finish()?;
    Ok(())
}

fn stimulus_report(s: &Stimulus<'_>) -> StimulusReport {
    let h = s.header();
    let bytes = s.as_bytes().len();
    let seconds = f64::from(h.duration_ms) / 1000.0;
    StimulusReport {
        kind: "stimulus",
        name: h.name.to_string(),
        version: stimulus::VERSION,
        channels: h.channels,
        output_rate_hz: h.output_rate_hz,
        keyframe_period_ms: h.keyframe_period_ms,
        keyframe_rate_hz: h.keyframe_rate_hz(),
        keyframes: h.keyframe_count,
        duration_s: seconds,
        ramp_ms: h.ramp_ms,
        full_scale_ma: h.full_scale_ma,
        resolution_ma: f64::from(h.full_scale_ma) * f64::from(1u32 << h.quant_shift) / 32768.0,
        layout: h.layout.to_string(),
        layout_hash: format!("{:#010x}", h.layout_hash),
        limits: Limits {
            peak_ma: h.limits.peak_ma,
            slew_ma_per_ms: h.limits.slew_ma_per_ms,
            continuous_ma: h.limits.continuous_ma,
            i2t_budget_ma2s: h.limits.i2t_budget_ma2s,
        },
        bytes,
        bytes_per_second: (seconds > 0.0).then(|| bytes as f64 / seconds),
        crc: format!("ok ({:#010x})", s.crc()),
    }
}

fn write_text(w: &mut impl Write, report: &Report) -> std::io::Result<()> {
    match report {
        Report::Bank(b) => {
            writeln!(
                w,
                "bank v{}, {} bytes, CRC {}, layout geometry {}",
                b.version, b.bytes, b.crc, b.layout_hash
            )?;
            for (i, slot) in b.slots.iter().enumerate() {
                write!(w, "slot {i}: ")?;
                write_stimulus(w, slot)?;
            }
            Ok(())
        }
        Report::Stimulus(s) => write_stimulus(w, s),
    }
}

/// Two lines about one stimulus; its name is escaped, since it comes from the file and
/// may hold terminal control codes.
fn write_stimulus(w: &mut impl Write, s: &StimulusReport) -> std::io::Result<()> {
    writeln!(
        w,
        "{} (stimulus v{}): {:.3} s of keyframes (plays {:.3} s with the {} ms ramp down), {} keyframes every {} ms, {} bytes ({} B/s), CRC {}",
        super::report::escaped(&s.name),
        s.version,
        s.duration_s,
        s.duration_s + f64::from(s.ramp_ms) / 1000.0,
        s.ramp_ms,
        s.keyframes,
        s.keyframe_period_ms,
        s.bytes,
        s.bytes_per_second.map_or("-".into(), |b| format!("{b:.0}")),
        s.crc,
    )?;
    let l = &s.limits;
    writeln!(
        w,
        "  full scale {} mA, resolution {:.3} mA, ramp {} ms, layout {} ({}); limits: peak {} mA, slew {} mA/ms, continuous {} mA, I2t {} mA2s",
        s.full_scale_ma,
        s.resolution_ma,
        s.ramp_ms,
        super::report::escaped(&s.layout),
        s.layout_hash,
        l.peak_ma,
        l.slew_ma_per_ms,
        l.continuous_ma,
        l.i2t_budget_ma2s,
    )
}
