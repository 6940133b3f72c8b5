//! `touchc bank A.touch B.touch ... -o sleeve.bank`: one slot per stimulus, in order.
//!
//! The bank is for one sleeve: every stimulus must have been compiled for its layout
//! (`--layout`, default the paper's 2 x 4 sleeve that the firmware drives) and its
//! eight channels, and the image must fit the firmware's bank flash region. Each
//! refusal names the file and gives both values.

use std::path::{Path, PathBuf};

use crate::cli::output::write_atomic;
use anyhow::{bail, Context};
use touch_protocol::{bank, container, Error, Stimulus, CHANNELS};

/// Arguments of `touchc bank`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Stimuli, one per slot, in slot order: slot 0 first (button 0, or the first short press).
    #[arg(required = true)]
    stimuli: Vec<PathBuf>,
    /// The bank image to write.
    #[arg(short, long)]
    output: PathBuf,
    /// The layout TOML of the sleeve the bank is for (default: the paper's 2 x 4
    /// sleeve, the one the firmware drives); every stimulus must be compiled for it.
    #[arg(long)]
    layout: Option<PathBuf>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    {
        use crate::cli::output::{named, refuse_overwrites};
        let mut inputs: Vec<_> = args
            .stimuli
            .iter()
            .map(|p| named("the stimulus", p))
            .collect();
        inputs.extend(args.layout.as_deref().map(|p| named("--layout", p)));
        refuse_overwrites(&inputs, &[named("-o", &args.output)])?;
    }
    let (image, slots) = build(&args.stimuli, args.layout.as_deref(), &args.output)?;
    write_atomic(&args.output, &image)?;
    eprintln!(
        "touchc: wrote {} ({} slots, {} of {} bytes of the bank region)",
        super::report::escaped(&crate::cli::output::shown(&args.output)),
        slots,
        image.len(),
        bank::REGION_LEN
    );
    Ok(())
}

/// The bank image of `stimuli`, one per slot, checked for the sleeve of `layout`
/// (default the paper's); errors about the bank as a whole name `bank_name`.
/// Returns the image and its number of slots.
pub(crate) fn build(
    stimuli: &[PathBuf],
    layout: Option<&Path>,
    bank_name: &Path,
) -> anyhow::Result<(Vec<u8>, usize)> {
    let layout = super::input::layout(layout)?;
    let target = layout.geometry_hash();
    if stimuli.len() > usize::from(bank::MAX_SLOTS) {
        return Err(super::report::usage(format!(
            "{}: {} stimuli, but a bank holds at most {} slots",
            bank_name.display(),
            stimuli.len(),
            bank::MAX_SLOTS
        )));
    }
    let files = stimuli
        .iter()
        .map(|path| {
            let bytes = super::input::read_input(path)?;
            check_fits(&bytes, path, target, layout.id())?;
            Ok(bytes)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let slices: Vec<&[u8]> = files.iter().map(Vec::as_slice).collect();
    let image = bank::encode(&slices)
        .with_context(|| format!("{}: cannot build the bank", bank_name.display()))?;
    Ok((image, slices.len()))
}

/// Checks that `bytes` is a stimulus for the target sleeve: valid, eight channels,
/// compiled for the layout geometry `target` (the layout file's id is `target_name`).
fn check_fits(bytes: &[u8], path: &Path, target: u32, target_name: &str) -> anyhow::Result<()> {
    let name = path.display();
    match Stimulus::decode(bytes) {
        Ok(s) => s.check_layout(target).map_err(|_| {
            let h = s.header();
            anyhow::anyhow!(
                "{name}: compiled for layout \"{}\" (geometry {:#010x}), but the bank is for \
                 layout \"{}\" (geometry {target:#010x}); compile it with that layout (--layout)",
                super::report::escaped(h.layout),
                h.layout_hash,
                super::report::escaped(target_name)
            )
        }),
        Err(Error::InvalidField("channels")) => {
            // The channel count is the header's first byte, after the framing.
            let found = bytes.get(container::PREFIX_LEN).copied().unwrap_or(0);
            bail!("{name}: has {found} channels, but the bank's sleeve has {CHANNELS}")
        }
        Err(e) => Err(e).with_context(|| format!("{name}: not a valid stimulus")),
    }
}
