//! `touchc bank A.touch B.touch ... -o sleeve.bank`: one slot per stimulus, in order.

use std::path::PathBuf;

use anyhow::Context;
use touch_protocol::{bank, Stimulus};
use touchc::output::write_atomic;

/// Arguments of `touchc bank`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Stimuli, one per slot, in slot order: slot 0 first (button 0, or the first short press).
    #[arg(required = true)]
    stimuli: Vec<PathBuf>,
    /// The bank image to write.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let files = args
        .stimuli
        .iter()
        .map(|path| {
            let bytes = super::read_input(path)?;
            Stimulus::decode(&bytes)
                .with_context(|| format!("{}: not a valid stimulus", path.display()))?;
            Ok(bytes)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let slices: Vec<&[u8]> = files.iter().map(Vec::as_slice).collect();
    let image = bank::encode(&slices)
        .with_context(|| format!("{}: cannot build the bank", args.output.display()))?;
    write_atomic(&args.output, &image)?;
    eprintln!(
        "touchc: wrote {} ({} slots, {} bytes)",
        args.output.display(),
        slices.len(),
        image.len()
    );
    Ok(())
}
