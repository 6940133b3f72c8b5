//! `touchc plot FILE -o out.svg|png`: the eight channels' currents as the sleeve
//! outputs them, one panel per actuator in the sleeve's layout.

use std::path::PathBuf;

use crate::cli::output::write_atomic;
use anyhow::Context;
use touch_protocol::DeviceConfig;
use touchc::viz::plot::{self, Format, Size};

/// Arguments of `touchc plot`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A `.touch` stimulus, or a `.bank` with `--slot` (`-`: standard input).
    file: PathBuf,
    /// The image to write; `.svg` or `.png` picks the format.
    #[arg(short, long)]
    output: PathBuf,
    /// Which slot of a bank to plot.
    /// 0 when not given.
    #[arg(long)]
    slot: Option<usize>,
    /// Image width, px.
    #[arg(long, default_value_t = Size::default().width)]
    width: u32,
    /// Image height, px.
    #[arg(long, default_value_t = Size::default().height)]
    height: u32,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let Some(format) = Format::from_extension(&args.output) else {
        return Err(super::report::usage(format!(
            "{}: name the output .svg or .png to choose the format",
            args.output.display()
        )));
    };
    let (min, max) = plot::SIDE_PX;
    for (flag, px) in [("--width", args.width), ("--height", args.height)] {
        if !(min..=max).contains(&px) {
            return Err(super::report::usage(format!(
                "{flag} {px} is out of range: must be {min} to {max} px"
            )));
        }
    }
    crate::cli::output::refuse_overwrites(
        &[crate::cli::output::named("the stimulus", &args.file)],
        &[crate::cli::output::named("-o", &args.output)],
    )?;
    let bytes = super::input::read_input(&args.file)?;
    let stimulus = super::input::stimulus_in(&bytes, &args.file, args.slot)?;
    super::input::warn_if_unplayable(&args.file, &stimulus);
    let size = Size {
        width: args.width,
        height: args.height,
    };
    let image = plot::plot(&stimulus, &DeviceConfig::default(), format, size)
        .with_context(|| format!("{}: cannot plot", super::input::input_name(&args.file)))?;
    write_atomic(&args.output, &image)?;
    Ok(())
}
