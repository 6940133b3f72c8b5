//! `touchc import FILE.hjif -o OUT.touch`: an MPEG-I Haptics file that `touchc export`
//! wrote (or one like it: eight linear-curve channels for the sleeve's layout) back
//! into a stimulus, encoded as `compile` encodes, so that an export can be checked by
//! playing its round trip.

use std::path::PathBuf;

use anyhow::Context;
use touch_protocol::{DeviceConfig, Limits};
use touchc_encoding::keyframes::{encode, HeaderFields, KeyframeOptions};
use touchc_export::hjif;
use touchc_model::config::KeyframeConfig;

use crate::cli::output::{is_stdio, named, refuse_overwrites, shown, write_atomic};

/// The share of the compile's error bounds (0.5% RMS, 2% max of full scale) the
/// re-encoding may use: the curves themselves are within 0.1% of the player's output,
/// so the stimulus that comes back stays within the compile's bounds of the original.
const IMPORT_BOUND_SHARE: f64 = 0.8;

/// Arguments of `touchc import`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// An `.hjif` file (`-`: standard input).
    file: PathBuf,
    /// The stimulus to write (`-`: standard output).
    #[arg(short, long)]
    output: PathBuf,
    /// The stimulus's name (default: the file's stem; `stdin` for standard input).
    #[arg(long)]
    name: Option<String>,
    /// The layout TOML of the sleeve (default: the paper's 2 x 4 sleeve); the file must
    /// name its geometry.
    #[arg(long)]
    layout: Option<PathBuf>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    {
        let mut inputs = vec![named("the file", &args.file)];
        inputs.extend(args.layout.as_deref().map(|p| named("--layout", p)));
        refuse_overwrites(&inputs, &[named("-o", &args.output)])?;
    }
    let layout = super::input::layout(args.layout.as_deref())?;
    let input = super::input::input_name(&args.file);
    // As `compile` names what it reads from standard input.
    let name = args.name.clone().unwrap_or_else(|| match &args.file {
        f if is_stdio(f) => "stdin".into(),
        f => f
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "imported".into()),
    });
    let name: String = name
        .char_indices()
        .take_while(|(i, c)| i + c.len_utf8() <= touch_protocol::stimulus::MAX_NAME_LEN)
        .map(|(_, c)| c)
        .collect();
    let bytes = super::input::read_input(&args.file)?;
    let device = DeviceConfig::default();
    let full_scale_a = f64::from(device.full_scale_ma) / 1000.0;
    let imported = hjif::import(&bytes, full_scale_a).with_context(|| input.clone())?;
    if imported.layout_hash != layout.geometry_hash() {
        anyhow::bail!(
            "{input}: written for the layout geometry {:#010x}, not for {:?} ({:#010x}); \
             give that layout with --layout",
            imported.layout_hash,
            layout.id(),
            layout.geometry_hash()
        );
    }
    let defaults = KeyframeConfig::default();
    let encoding = KeyframeConfig {
        max_rms_error_fs: defaults.max_rms_error_fs * IMPORT_BOUND_SHARE,
        max_abs_error_fs: defaults.max_abs_error_fs * IMPORT_BOUND_SHARE,
        ..defaults
    };
    let encoded = encode(
        &imported.signal,
        HeaderFields {
            name: &name,
            layout_hash: layout.geometry_hash(),
            layout: layout.id(),
            limits: Limits::SLEEVE,
        },
        &KeyframeOptions::new(&encoding),
    )
    .with_context(|| format!("{input}: cannot encode"))?;
    write_atomic(&args.output, &encoded.bytes)?;
    let seconds = imported.signal.len() as f64 / 1000.0;
    eprintln!(
        "{}",
        super::report::escaped(&format!(
            "touchc: {input} -> {}: {seconds:.2} s, {} bytes ({:.0} B/s), keyframes every {} ms, \
             error {:.3}% RMS / {:.3}% max of full scale against the file's curves",
            shown(&args.output),
            encoded.bytes.len(),
            encoded.bytes.len() as f64 / seconds.max(1e-3),
            encoded.period_ms,
            100.0 * encoded.rms_error_fs,
            100.0 * encoded.max_error_fs,
        ))
    );
    Ok(())
}
