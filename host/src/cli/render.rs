//! `touchc render FILE --csv`: the player's 1 kHz output, from the same code the
//! firmware runs.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use touch_protocol::player::code_to_amps;
use touch_protocol::{bank, Bank, DeviceConfig, Player, Status, Stimulus};
use touchc::output::write_atomic;

/// Arguments of `touchc render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A `.touch` stimulus, or a `.bank` with `--slot`.
    file: PathBuf,
    /// Write CSV: `t_s,ch0,...,ch7`, currents in amperes, one row per 1 kHz tick.
    #[arg(long)]
    csv: bool,
    /// Where to write (default: standard output).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Which slot of a bank to render.
    #[arg(long, default_value_t = 0)]
    slot: usize,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !args.csv {
        bail!("choose an output format: --csv");
    }
    let bytes = super::read_input(&args.file)?;
    let name = args.file.display();
    let stimulus = if bytes.starts_with(&bank::MAGIC) {
        let bank = Bank::decode(&bytes).with_context(|| format!("{name}: not a valid bank"))?;
        bank.slot(args.slot)
            .with_context(|| format!("{name}: slot {}", args.slot))?
    } else {
        Stimulus::decode(&bytes).with_context(|| format!("{name}: not a valid stimulus"))?
    };
    let device = DeviceConfig::default();
    let csv = render_csv(&stimulus, &device);
    match &args.output {
        Some(path) => write_atomic(path, csv.as_bytes())?,
        None => print!("{csv}"),
    }
    Ok(())
}

/// One CSV row per tick until the player finishes; a fault is reported on stderr.
fn render_csv(stimulus: &Stimulus<'_>, device: &DeviceConfig) -> String {
    let mut out = String::from("t_s,ch0,ch1,ch2,ch3,ch4,ch5,ch6,ch7\n");
    let mut player = Player::new(stimulus, device);
    for (t, tick) in player.by_ref().enumerate() {
        let _ = write!(out, "{:.3}", t as f64 / 1000.0);
        for code in tick.codes {
            let _ = write!(out, ",{:.6}", code_to_amps(code, device.full_scale_ma));
        }
        out.push('\n');
        if let Status::Fault(f) = tick.status {
            eprintln!(
                "touchc: warning: {:?} limit hit on channel {} at {:.3} s; the player ramped to 0 A",
                f.kind,
                f.channel,
                t as f64 / 1000.0
            );
        }
    }
    out
}
