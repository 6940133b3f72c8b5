//! `touchc inspect FILE`: what is in a stimulus or bank file, and whether it is intact.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use serde_json::{json, Value};
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

pub fn run(args: &Args) -> anyhow::Result<()> {
    let bytes = super::read_input(&args.file)?;
    let name = super::input_name(&args.file);
    let report = if bytes.starts_with(&bank::MAGIC) {
        let bank = Bank::decode(&bytes).with_context(|| format!("{name}: not a valid bank"))?;
        let slots: Vec<Value> = bank.stimuli().map(|s| stimulus_json(&s)).collect();
        json!({
            "kind": "bank",
            "version": bank::VERSION,
            "bytes": bank.as_bytes().len(),
            "crc": "ok",
            "slots": slots,
        })
    } else {
        match Stimulus::decode(&bytes) {
            Ok(s) => stimulus_json(&s),
            Err(e @ Error::BadCrc { .. }) => bail!("{name}: CRC check failed: {e}"),
            Err(e) => bail!("{name}: not a valid stimulus: {e}"),
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

fn stimulus_json(s: &Stimulus<'_>) -> Value {
    let h = s.header();
    let bytes = s.as_bytes().len();
    let seconds = f64::from(h.duration_ms) / 1000.0;
    let resolution_ma = f64::from(h.full_scale_ma) * f64::from(1u32 << h.quant_shift) / 32768.0;
    json!({
        "kind": "stimulus",
        "name": h.name,
        "version": stimulus::VERSION,
        "channels": h.channels,
        "output_rate_hz": h.output_rate_hz,
        "keyframe_period_ms": h.keyframe_period_ms,
        "keyframe_rate_hz": h.keyframe_rate_hz(),
        "keyframes": h.keyframe_count,
        "duration_s": seconds,
        "ramp_ms": h.ramp_ms,
        "full_scale_ma": h.full_scale_ma,
        "resolution_ma": resolution_ma,
        "layout_id": h.layout_id,
        "limits": {
            "peak_ma": h.limits.peak_ma,
            "slew_ma_per_ms": h.limits.slew_ma_per_ms,
            "continuous_ma": h.limits.continuous_ma,
            "i2t_budget_ma2s": h.limits.i2t_budget_ma2s,
        },
        "bytes": bytes,
        "bytes_per_second": if seconds > 0.0 { Value::from(bytes as f64 / seconds) } else { Value::Null },
        "crc": format!("ok ({:#010x})", s.crc()),
    })
}

fn write_text(w: &mut impl Write, report: &Value) -> std::io::Result<()> {
    if report["kind"] == "bank" {
        writeln!(
            w,
            "bank v{}, {} bytes, CRC {}",
            report["version"], report["bytes"], report["crc"]
        )?;
        for (i, slot) in report["slots"].as_array().into_iter().flatten().enumerate() {
            write!(w, "slot {i}: ")?;
            write_stimulus(w, slot)?;
        }
        Ok(())
    } else {
        write_stimulus(w, report)
    }
}

/// Two lines about one stimulus; its name is escaped, since it comes from the file and
/// may hold terminal control codes.
fn write_stimulus(w: &mut impl Write, s: &Value) -> std::io::Result<()> {
    writeln!(
        w,
        "{} (stimulus v{}): {:.3} s, {} keyframes every {} ms, {} bytes ({} B/s), CRC {}",
        super::escaped(s["name"].as_str().unwrap_or("")),
        s["version"],
        s["duration_s"].as_f64().unwrap_or(0.0),
        s["keyframes"],
        s["keyframe_period_ms"],
        s["bytes"],
        s["bytes_per_second"]
            .as_f64()
            .map_or("-".into(), |b| format!("{b:.0}")),
        s["crc"].as_str().unwrap_or(""),
    )?;
    writeln!(
        w,
        "  full scale {} mA, resolution {:.3} mA, ramp {} ms, layout {}; limits: peak {} mA, slew {} mA/ms, continuous {} mA, I2t {} mA2s",
        s["full_scale_ma"],
        s["resolution_ma"].as_f64().unwrap_or(0.0),
        s["ramp_ms"],
        s["layout_id"],
        s["limits"]["peak_ma"],
        s["limits"]["slew_ma_per_ms"],
        s["limits"]["continuous_ma"],
        s["limits"]["i2t_budget_ma2s"],
    )
}
