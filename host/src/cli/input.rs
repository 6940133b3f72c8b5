//! Reading the inputs: regular files whole, streams (standard input, pipes, devices)
//! with a bound, since they may never end (`touchc inspect /dev/zero`).

use std::io::Read;
use std::path::Path;

use anyhow::Context;

use touch_protocol::{Bank, Stimulus};

use super::report::{message, usage};

/// The most bytes read from a stream (standard input, a pipe, a device) for one
/// stimulus, bank or `.hjif` file: 512 MiB, far beyond what `touchc` writes (a bank
/// fits the sleeve's 256 KiB region), so an endless stream ends in an error, not in
/// running out of memory.
const STREAM_BUDGET_BYTES: u64 = 1 << 29;

/// Reads a whole input file, `-` being standard input, naming it in the error. A
/// regular file is read whole (its size is on the disk); a stream may never end, so it
/// is read by [`read_stream`].
pub(crate) fn read_input(path: &Path) -> anyhow::Result<Vec<u8>> {
    let name = input_name(path);
    if crate::cli::output::is_stdio(path) {
        return read_stream(&name, &mut std::io::stdin().lock());
    }
    let mut file = std::fs::File::open(path).with_context(|| format!("{name}: cannot read"))?;
    let meta = file
        .metadata()
        .with_context(|| format!("{name}: cannot read"))?;
    if !meta.is_file() {
        return read_stream(&name, &mut file);
    }
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)
        .with_context(|| format!("{name}: cannot read"))?;
    Ok(bytes)
}

/// Reads a stimulus, a bank or a JSON file from a stream, looking before it reads: a
/// stimulus or bank is read up to the length its prefix claims (and one byte more, so
/// that trailing data is still reported), JSON up to [`STREAM_BUDGET_BYTES`], and
/// anything else stops after the first bytes, which are enough for the decoder to name
/// what is wrong (a bad magic number).
fn read_stream(name: &str, reader: &mut dyn Read) -> anyhow::Result<Vec<u8>> {
    use touch_protocol::container::PREFIX_LEN;
    let io = || format!("{name}: cannot read");
    let mut bytes = Vec::new();
    read_up_to(reader, &mut bytes, PREFIX_LEN as u64).with_context(io)?;
    let container = [touch_protocol::stimulus::MAGIC, touch_protocol::bank::MAGIC]
        .iter()
        .any(|m| bytes.starts_with(m));
    let limit = if container && bytes.len() == PREFIX_LEN {
        let claimed = u32::from_le_bytes([bytes[6], bytes[7], bytes[8], bytes[9]]);
        u64::from(claimed).min(STREAM_BUDGET_BYTES) + 1
    } else if bytes.first().is_some_and(|b| b"{[ \t\r\n".contains(b)) {
        STREAM_BUDGET_BYTES + 1
    } else {
        return Ok(bytes);
    };
    read_up_to(reader, &mut bytes, limit).with_context(io)?;
    if bytes.len() as u64 > STREAM_BUDGET_BYTES {
        anyhow::bail!(
            "{name}: more than {STREAM_BUDGET_BYTES} bytes arrive, and no stimulus, bank or \
             .hjif file is that large"
        );
    }
    Ok(bytes)
}

/// Reads from `reader` until `bytes` holds `total` bytes or the stream ends.
fn read_up_to(reader: &mut dyn Read, bytes: &mut Vec<u8>, total: u64) -> std::io::Result<()> {
    let more = total.saturating_sub(bytes.len() as u64);
    reader.take(more).read_to_end(bytes)?;
    Ok(())
}

/// Loads a recording, `-` being standard input (`touchc synth ... -o - | touchc compile -`).
pub(crate) fn load_recording(path: &Path) -> anyhow::Result<touchc_input::recording::Recording> {
    use touchc_input::recording::Recording;
    if crate::cli::output::is_stdio(path) {
        let name = input_name(path);
        return Ok(Recording::read_from(name, &mut std::io::stdin().lock())?);
    }
    Ok(Recording::load(path)?)
}

/// Refuses a recording whose own rate or pitch (a `.npz`'s `rate_hz`, `pitch_mm`)
/// makes a knob of `config` impossible, as bad input (exit status 1) that names the
/// file's value, before the library would report the knob as a usage error: nothing
/// on the command line is wrong, the file is. Values from the command line or the
/// config are left to the library's usage error.
pub(crate) fn check_file_sampling(
    recording: &touchc_input::recording::Recording,
    config: &touchc_model::config::ValidConfig,
    overrides: &touchc_model::config::MetadataOverrides,
) -> anyhow::Result<()> {
    use touchc_model::config::{Metadata, Sampling, Source};
    let metadata = Metadata::resolve(overrides, &recording.file_metadata(), config);
    if metadata.rate_hz.source != Source::File && metadata.pitch_mm.source != Source::File {
        return Ok(());
    }
    let sampling = Sampling::new(&metadata, config);
    let (_, rows, cols) = recording.dim();
    let Err(e) = config.validate_for(&sampling, (rows, cols)) else {
        return Ok(());
    };
    let mut declared = Vec::new();
    if metadata.rate_hz.source == Source::File {
        declared.push(format!("rate_hz = {} Hz", metadata.rate_hz.value));
    }
    if metadata.pitch_mm.source == Source::File {
        declared.push(format!("pitch_mm = {} mm", metadata.pitch_mm.value));
    }
    anyhow::bail!(
        "{}: the file's {} cannot be compiled: {} (if the file is wrong, give the right \
         value with --rate or --pitch-mm)",
        recording.name(),
        declared.join(" and "),
        e
    )
}

/// Warns when `stimulus` can never play on the sleeve: limits that let nothing move
/// (a peak or a slew of 0) stop the player before its first tick, so a render or a
/// plot is empty and an export silent, with nothing else to say why.
pub(crate) fn warn_if_unplayable(path: &Path, stimulus: &touch_protocol::Stimulus<'_>) {
    let device = touch_protocol::DeviceConfig::default();
    if touchc::viz::play(stimulus, &device).next().is_some() {
        return;
    }
    let limits = stimulus.limits().min(device.limits);
    super::report::warn(
        path,
        &format!(
            "the stimulus can never play: its limits (peak {} mA, slew {} mA/ms, with the \
             sleeve's) let no current move, so the player stops before its first tick and \
             the output is empty; compile it again with limits above 0",
            limits.peak_ma, limits.slew_ma_per_ms
        ),
    );
}

/// The most bytes of a text input read (a `--config` or `--truth` file): 64 MiB, far
/// more than any of them holds, so that `/dev/zero` ends in an error.
pub(crate) const MAX_TEXT_BYTES: u64 = 1 << 26;

/// Reads the text file `path`, at most `max` bytes of it: more is an error.
pub(crate) fn read_text(path: &Path, max: u64) -> std::io::Result<String> {
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(max + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > max {
        return Err(std::io::Error::other(format!(
            "more than {max} bytes, far more than such a file holds"
        )));
    }
    Ok(text)
}

/// A default as `--help` shows it: 3 pixels of 25.4/7 mm is 10.885714285714286, shown
/// with the digits a person can use.
pub(crate) fn rounded(text: String) -> String {
    match text.parse::<f64>() {
        Ok(v) if text.len() > 8 => format!("{v:.3}, rounded"),
        _ => text,
    }
}

/// The actuator layout of a `--layout FILE` option, or the paper's sleeve without one.
/// A layout file that cannot be read or is not a layout is a usage error, like a
/// `--config` file: both are how the command was called.
pub(crate) fn layout(path: Option<&Path>) -> anyhow::Result<touchc_model::layout::Layout> {
    Ok(match path {
        Some(path) => touchc_model::layout::Layout::load(path)
            .map_err(|e| usage(message(&anyhow::Error::new(e))))?,
        None => touchc_model::layout::Layout::paper(),
    })
}

/// How an input path is named in messages (`-` is standard input).
pub(crate) fn input_name(path: &Path) -> String {
    if crate::cli::output::is_stdio(path) {
        "standard input".into()
    } else {
        path.display().to_string()
    }
}

/// The stimulus in `bytes`: the file itself, or slot `slot` (`--slot`, 0 when not
/// given) when it is a bank. A `--slot` above 0 on a stimulus is a usage error: a
/// stimulus is its own only slot, and ignoring it would let a mistake pass.
pub(crate) fn stimulus_in<'a>(
    bytes: &'a [u8],
    path: &Path,
    slot: Option<usize>,
) -> anyhow::Result<Stimulus<'a>> {
    let name = input_name(path);
    if bytes.starts_with(&touch_protocol::bank::MAGIC) {
        let bank = Bank::decode(bytes).with_context(|| format!("{name}: not a valid bank"))?;
        let slot = slot.unwrap_or(0);
        if slot >= bank.len() {
            anyhow::bail!(
                "{name}: no slot {slot}: the bank has {} slot(s), 0 to {} (--slot)",
                bank.len(),
                bank.len() - 1
            );
        }
        bank.slot(slot)
            .with_context(|| format!("{name}: slot {slot}"))
    } else if let Some(slot) =
        slot.filter(|&s| s > 0 && bytes.starts_with(&touch_protocol::stimulus::MAGIC))
    {
        Err(usage(format!(
            "--slot {slot}: {name} is a stimulus, not a bank; --slot picks a stimulus out of \
             a bank"
        )))
    } else {
        Stimulus::decode(bytes).with_context(|| format!("{name}: not a valid stimulus"))
    }
}
