//! `touchc export FILE --to hjif|haptic|ahap|tact [-o OUT]`: a stimulus as the sleeve
//! plays it, in another haptics format (see `touchc_export` and docs/export.md).

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use anyhow::Context;
use touchc_export::{ExportOptions, Format, Pick};

use crate::cli::output::{is_stdio, named, refuse_overwrites, shown, write_atomic};

/// The formats, as the command line names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum To {
    /// MPEG-I Haptics interchange format (ISO/IEC 23090-31), all eight channels.
    Hjif,
    /// Meta/Lofelt .haptic, one file per actuator (or --channel / --mix).
    Haptic,
    /// Apple Core Haptics AHAP, one file per actuator (or --channel / --mix).
    Ahap,
    /// bHaptics .tact, the six motors of a forearm device.
    Tact,
}

impl To {
    fn format(self) -> Format {
        match self {
            To::Hjif => Format::Hjif,
            To::Haptic => Format::Haptic,
            To::Ahap => Format::Ahap,
            To::Tact => Format::Tact,
        }
    }
}

/// Arguments of `touchc export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A `.touch` stimulus, or a `.bank` with `--slot` (`-`: standard input).
    file: PathBuf,
    /// The format to write.
    #[arg(long, value_enum)]
    to: To,
    /// Where to write (default: beside FILE, with the format's extension; `-`: standard
    /// output). For .haptic and .ahap without --channel or --mix, one file per actuator:
    /// OUT.ch0.haptic ...
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Which slot of a bank to export.
    /// 0 when not given.
    #[arg(long)]
    slot: Option<usize>,
    /// For .haptic and .ahap: only this actuator's channel (0 to 7), in one file.
    #[arg(long, conflicts_with = "mix")]
    channel: Option<usize>,
    /// For .haptic and .ahap: one file of the eight channels mixed (the most pressed
    /// at each moment, the largest current).
    #[arg(long)]
    mix: bool,
    /// The layout TOML of the sleeve the stimulus is for (default: the paper's 2 x 4
    /// sleeve); a stimulus compiled for another layout is refused.
    #[arg(long)]
    layout: Option<PathBuf>,
    /// For .hjif: the actuator's mechanical resonance in Hz (1 to 20000), written into
    /// the reference device (left out by default: the coil's datasheet value is the
    /// maker's to give).
    #[arg(long, value_name = "HZ")]
    resonance_hz: Option<f64>,
}

/// Highest resonance `--resonance-hz` takes, Hz: the top of human vibrotactile and
/// auditory range, beyond any voice coil's first mode.
const MAX_RESONANCE_HZ: f64 = 20_000.0;

pub fn run(args: &Args) -> anyhow::Result<()> {
    let format = args.to.format();
    let pick = checked_pick(args, format)?;
    let outputs = output_paths(args, format, pick.is_none())?;
    {
        let mut inputs = vec![named("the stimulus", &args.file)];
        inputs.extend(args.layout.as_deref().map(|p| named("--layout", p)));
        let outs: Vec<_> = outputs.iter().map(|p| named("-o", p)).collect();
        refuse_overwrites(&inputs, &outs)?;
    }
    let layout = super::input::layout(args.layout.as_deref())?;
    let bytes = super::input::read_input(&args.file)?;
    let stimulus = super::input::stimulus_in(&bytes, &args.file, args.slot)?;
    super::input::warn_if_unplayable(&args.file, &stimulus);
    let name = super::input::input_name(&args.file);
    let playback = touchc_export::play(&stimulus, &layout).with_context(|| name.clone())?;
    if let Some(f) = playback.fault {
        super::report::warn(&args.file, &touchc::viz::describe_fault(f));
    }
    let exported = touchc_export::export(
        &playback,
        format,
        &ExportOptions {
            pick,
            date: today(),
            resonance_hz: args.resonance_hz,
        },
    )
    .with_context(|| format!("{name}: cannot export"))?;
    for (file, path) in exported.files.iter().zip(&outputs) {
        write_atomic(path, &file.bytes)?;
    }
    let line = summary(&name, &outputs, &playback, &exported, format);
    eprintln!("{}", super::report::escaped(&line));
    Ok(())
}

/// The signal `--channel` or `--mix` picks (none: every channel), once the flags that
/// only some formats take are checked against `format`.
fn checked_pick(args: &Args, format: Format) -> anyhow::Result<Option<Pick>> {
    let pick = match (args.channel, args.mix) {
        (Some(c), _) => Some(Pick::Channel(c)),
        (None, true) => Some(Pick::Mix),
        (None, false) => None,
    };
    if pick.is_some() && !format.single_signal() {
        return Err(super::report::usage(format!(
            "--channel and --mix are for --to haptic and --to ahap: a .{} file holds every channel",
            format.extension()
        )));
    }
    if let Some(c) = args.channel {
        if c >= touch_protocol::CHANNELS {
            return Err(super::report::usage(format!(
                "--channel {c}: the sleeve has channels 0 to {}",
                touch_protocol::CHANNELS - 1
            )));
        }
    }
    if let Some(hz) = args.resonance_hz {
        if format != Format::Hjif {
            return Err(super::report::usage(format!(
                "--resonance-hz is for --to hjif: a .{} file has no device description",
                format.extension()
            )));
        }
        if !(1.0..=MAX_RESONANCE_HZ).contains(&hz) {
            return Err(super::report::usage(format!(
                "--resonance-hz {}: give the resonance in Hz, 1 to {}",
                touchc_model::display::Shortest(hz),
                touchc_model::display::Shortest(MAX_RESONANCE_HZ)
            )));
        }
    }
    Ok(pick)
}

/// The files to write: `-o` (or FILE's name with the format's extension), once, or
/// once per actuator for a single-signal format with no `--channel` or `--mix`
/// (`every_channel`).
fn output_paths(args: &Args, format: Format, every_channel: bool) -> anyhow::Result<Vec<PathBuf>> {
    let suffixes: Vec<String> = if format.single_signal() && every_channel {
        (0..touch_protocol::CHANNELS)
            .map(|c| format!(".ch{c}"))
            .collect()
    } else {
        vec![String::new()]
    };
    let base = match &args.output {
        Some(p) => p.clone(),
        None if is_stdio(&args.file) => {
            return Err(super::report::usage(
                "the stimulus comes from standard input: name the output with -o",
            ))
        }
        None => default_output(&args.file, args.slot.unwrap_or(0), format),
    };
    if args.output.is_some() && !is_stdio(&base) {
        check_output_name(&base, format, suffixes.len() > 1)?;
    }
    if is_stdio(&base) && suffixes.len() > 1 {
        return Err(super::report::usage(format!(
            "--to {}: one file per actuator cannot go to standard output: give -o FILE, \
             --channel N or --mix",
            format.extension()
        )));
    }
    Ok(suffixes
        .iter()
        .map(|s| with_suffix(&base, s, format))
        .collect())
}

/// The extensions of the files `touchc` reads and writes: an `-o` with one of them
/// that is not the format's own would write, say, AHAP JSON into `y.touch`.
const KNOWN_EXTENSIONS: [&str; 13] = [
    "touch", "bank", "npy", "npz", "hjif", "haptic", "ahap", "tact", "wav", "csv", "svg", "png",
    "gif",
];

/// Refuses an `-o` that names another format's file, or a device or pipe when one
/// file per actuator is to be written beside it (`/dev/full.ch0.haptic`).
fn check_output_name(out: &Path, format: Format, per_channel: bool) -> anyhow::Result<()> {
    let want = format.extension();
    if let Some(ext) = out.extension().and_then(|e| e.to_str()) {
        let ext = ext.to_ascii_lowercase();
        if ext != want && KNOWN_EXTENSIONS.contains(&ext.as_str()) {
            return Err(super::report::usage(format!(
                "-o {}: a .{ext} name for a --to {want} file; name it .{want}",
                out.display()
            )));
        }
    }
    let special = std::fs::metadata(out).is_ok_and(|m| !m.is_file() && !m.is_dir());
    if per_channel && special {
        return Err(super::report::usage(format!(
            "-o {}: --to {want} writes one file per actuator beside it, and it is a device \
             or a pipe: give --channel N or --mix for one file",
            out.display()
        )));
    }
    Ok(())
}

/// The line that says what was written: where, how long, how large and how close to
/// the player's output.
fn summary(
    name: &str,
    outputs: &[PathBuf],
    playback: &touchc_export::Playback,
    exported: &touchc_export::Exported,
    format: Format,
) -> String {
    let f = exported.fidelity;
    let shown_out = match outputs {
        [one] => shown(one),
        many => format!(
            "{} ... {} ({} files)",
            shown(&many[0]),
            shown(&many[many.len() - 1]),
            many.len()
        ),
    };
    let seconds = playback.seconds();
    let mut line = format!(
        "touchc: {name} -> {shown_out}: plays {:.2} s, {} bytes ({:.0} B/s), error {:.3}% RMS / {:.3}% max of full scale against the player's output",
        seconds,
        exported.bytes(),
        exported.bytes() as f64 / seconds.max(1e-3),
        100.0 * f.rms_fs,
        100.0 * f.max_fs,
    );
    if format == Format::Tact {
        line.push_str(&format!(
            " (the motors' own fit {:.3}% RMS / {:.3}% max; the rest is the 8 actuators on 6 motors)",
            100.0 * f.fit_rms_fs,
            100.0 * f.fit_max_fs
        ));
    }
    line
}

/// FILE with the format's extension (and the slot, for a bank), beside it.
fn default_output(file: &Path, slot: usize, format: Format) -> PathBuf {
    let bank = file.extension().is_some_and(|e| e == "bank");
    let mut name: OsString = file.file_stem().unwrap_or(file.as_os_str()).to_owned();
    if bank {
        name.push(format!(".slot{slot}"));
    }
    name.push(format!(".{}", format.extension()));
    file.with_file_name(name)
}

/// `base` with `suffix` before its extension (`love.haptic` + `.ch3` ->
/// `love.ch3.haptic`); a base without an extension gets the format's.
fn with_suffix(base: &Path, suffix: &str, format: Format) -> PathBuf {
    if suffix.is_empty() || is_stdio(base) {
        return base.to_path_buf();
    }
    let ext = base
        .extension()
        .map(|e| e.to_owned())
        .unwrap_or_else(|| format.extension().into());
    let mut name: OsString = base.file_stem().unwrap_or(base.as_os_str()).to_owned();
    name.push(suffix);
    name.push(".");
    name.push(ext);
    base.with_file_name(name)
}

/// Today's date in UTC, `YYYY-MM-DD` (the civil calendar from days since 1970).
pub(crate) fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let days = (secs / 86_400) as i64;
    // Howard Hinnant's days-to-civil, in eras of 400 years.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_named_per_actuator_before_the_extension() {
        let p = with_suffix(Path::new("out/love.haptic"), ".ch3", Format::Haptic);
        assert_eq!(p, PathBuf::from("out/love.ch3.haptic"));
        let p = with_suffix(Path::new("love"), ".ch0", Format::Ahap);
        assert_eq!(p, PathBuf::from("love.ch0.ahap"));
        let p = default_output(Path::new("e/emoji.bank"), 2, Format::Hjif);
        assert_eq!(p, PathBuf::from("e/emoji.slot2.hjif"));
        let p = default_output(Path::new("love.touch"), 0, Format::Tact);
        assert_eq!(p, PathBuf::from("love.tact"));
    }

    #[test]
    fn today_is_a_date() {
        let d = today();
        assert_eq!(d.len(), 10, "{d}");
        assert!(d.starts_with("20"), "{d}");
    }
}
