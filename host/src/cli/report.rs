//! What `touchc` says when something goes wrong: usage errors and their exit status, an
//! error's chain in the command line's words with its advice, warnings, and the
//! clipping and escaping every message gets. Every subcommand reports through here.

use std::path::Path;
use std::process::ExitCode;

use touchc_model::config::{ConfigError, OffTable, Preset};

use super::input::input_name;

/// A mistake in how the command was called (exit status 2, like clap's own): a flag's
/// value, a parameter file, outputs that would overwrite inputs.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct Usage(pub String);

/// Returns a usage error (exit status 2).
pub(crate) fn usage(message: impl Into<String>) -> anyhow::Error {
    Usage(message.into()).into()
}

/// Prints `err` once on stderr and chooses the exit status: 2 for usage errors, 0 when
/// a reader closed our output pipe (the reader got what it wanted), 1 for the rest.
pub fn report(err: &anyhow::Error) -> ExitCode {
    let broken_pipe = err.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
            || cause
                .downcast_ref::<crate::cli::output::WriteError>()
                .is_some_and(crate::cli::output::WriteError::is_broken_pipe)
    });
    if broken_pipe {
        return ExitCode::SUCCESS;
    }
    // Ctrl-C during `select`'s training: stopped as asked, nothing written (128 + SIGINT).
    if err.chain().any(|c| {
        matches!(
            c.downcast_ref(),
            Some(touchc_select::SelectError::Cancelled)
        )
    }) {
        eprintln!("touchc: interrupted: nothing written");
        return ExitCode::from(130);
    }
    print_error(err);
    // A parameter out of range is a usage error wherever it is found: in the flags, or
    // only once the recording's sampling is known (a blur wider than the frame).
    if err
        .chain()
        .any(|cause| cause.is::<Usage>() || cause.is::<touchc_model::config::ConfigError>())
    {
        ExitCode::from(2)
    } else {
        ExitCode::FAILURE
    }
}

/// Prints `err` on stderr: its chain once, on one line, escaped and clipped.
pub(crate) fn print_error(err: &anyhow::Error) {
    eprintln!("touchc: error: {}", readable(&message(err)));
}

/// The error's chain joined by ": ", each cause said once: a TOML error in one line
/// (where, then what) instead of its multi-line picture of the offending line, and,
/// after the whole account, the advice that puts a cause right. The project's errors
/// never repeat their source's text (the chain carries it); a cause from another crate
/// whose text its outer error already ended with is left out.
pub(crate) fn message(err: &anyhow::Error) -> String {
    let mut out = String::new();
    // A cause's advice follows the account of it, which its sources end.
    let mut advised = String::new();
    for cause in err.chain() {
        let text = if let Some(e) = cause.downcast_ref::<toml::de::Error>() {
            toml_message(e)
        } else {
            advised.extend(advice(cause));
            cause.to_string()
        };
        if text.is_empty() || out.ends_with(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out + &advised
}

/// What to try, after the library's account of an error that a flag, a knob or another
/// file can put right.
fn advice(cause: &(dyn std::error::Error + 'static)) -> Option<String> {
    use touchc_input::recording::RecordingError;
    use touchc_model::config::SamplingKnob;
    use touchc_pipeline::compile::CompileError;
    use touchc_tracking::track::TrackError;
    if let Some(touch_protocol::Error::BadMagic { found, .. }) = cause.downcast_ref() {
        if found[..] == [0x93, b'N', b'U', b'M'] || found[..] == *b"PK\x03\x04" {
            return Some(
                " (it is a recording, .npy or .npz: compile it into a stimulus first with \
                 touchc compile)"
                    .into(),
            );
        }
    }
    if let Some(ConfigError::SamplingOutOfRange { knob, .. }) = cause.downcast_ref() {
        return Some(match knob {
            SamplingKnob::RateHz => " (--rate)".into(),
            SamplingKnob::PitchMm => " (--pitch-mm)".into(),
        });
    }
    let compile = cause.downcast_ref::<CompileError>();
    let track = match compile {
        Some(CompileError::Limits(_)) => return Some(" (use --fit to scale it down)".into()),
        Some(CompileError::Track(e)) => Some(e),
        _ => cause.downcast_ref::<TrackError>(),
    };
    let recording = match (compile, track) {
        (_, Some(TrackError::TooDense { .. })) => {
            return Some("; check the tare, or narrow the link gate with --max-speed-mm-s".into())
        }
        (Some(CompileError::Recording(e)), _) => Some(e),
        _ => cause.downcast_ref::<RecordingError>(),
    };
    match recording? {
        RecordingError::MemberTooLarge { .. } => {
            Some("; save the array as a .npy file instead".into())
        }
        RecordingError::Text { name, .. } => Some(format!(
            "; a CSV of one frame per line (rows x cols values in psi) converts with one line \
             of numpy: python3 -c 'import numpy as np; np.save(\"recording.npy\", \
             np.loadtxt(\"{name}\", delimiter=\",\").reshape(-1, ROWS, COLS))' with ROWS \
             and COLS the sensor's grid (8 and 21 for the paper's sleeve)"
        )),
        RecordingError::TooShort { .. } => Some(format!(
            " ({}, {})",
            touchc_model::config::Knob::InputTareS,
            touchc_model::config::Knob::InputTrimS
        )),
        _ => None,
    }
}

/// A config layer's error as a usage error (exit status 2) that names the flag of the
/// layer in error
/// (`--config`'s file, the `--set`s, `--preset`); a knob out of range in its own words
/// (`config/words.rs` in the model words the layers without flags).
pub(crate) fn config_usage(e: ConfigError) -> anyhow::Error {
    // The TOML error itself, not its box, so that the message gives it in one line.
    let within = |source: Box<toml::de::Error>, what: String| {
        message(&anyhow::Error::new(*source).context(what))
    };
    let text = match e {
        ConfigError::File { name, source } => within(source, format!("{name}: invalid config")),
        ConfigError::AssignmentSyntax { assignment } => {
            format!("--set {}: expected SECTION.KEY=VALUE", clip(&assignment))
        }
        ConfigError::AssignmentValue { assignment, source } => within(
            source,
            format!("--set {}: not a TOML value", clip(&assignment)),
        ),
        ConfigError::Keys {
            assignments,
            off,
            preset,
            source,
        } => {
            let what = if assignments.is_empty() {
                "invalid parameter".to_string()
            } else {
                let sets: Vec<String> = assignments.iter().map(|s| clip(s)).collect();
                format!("--set {}: invalid parameter", sets.join(" --set "))
            };
            let text = within(source, what);
            let mut off: Vec<String> = off.iter().map(|t| explain(t, preset)).collect();
            off.sort();
            off.dedup();
            if off.is_empty() {
                text
            } else {
                format!("{text}; {}", off.join("; "))
            }
        }
        other => message(&anyhow::Error::new(other).context("config")),
    };
    usage(text)
}

/// Why a `--set` into a table `preset` leaves out cannot be taken alone, and what would
/// do.
fn explain(t: &OffTable, preset: Preset) -> String {
    format!(
        "`{}` is off under --preset {}: set its keys ({}) or start from --preset {}",
        t.table,
        preset.name(),
        t.keys.join(", "),
        Preset::default().name()
    )
}

/// A TOML error in one line: `line 2, column 9: <what>`, or `<what> (in `key`)` for a
/// value of the wrong kind, without the echo of the document's line (which can be
/// megabytes long).
fn toml_message(e: &toml::de::Error) -> String {
    let what = e
        .message()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let display = e.to_string();
    if let Some(at) = display
        .lines()
        .next()
        .and_then(|l| l.strip_prefix("TOML parse error at "))
    {
        return format!("{at}: {what}");
    }
    match display.lines().find_map(|l| l.strip_prefix("in `")) {
        Some(key) => format!("{what} (in `{})", key.trim()),
        None => what,
    }
}

/// Longest piece of user text (a quoted value, a `--set` assignment) a message
/// repeats; longer ones are cut with an ellipsis.
pub(crate) const MAX_ECHO: usize = 80;
/// Longest message, in characters: a last resort for user text that [`readable`] did
/// not recognise as such, set above the longest sentence `touchc` writes itself (a
/// coverage warning with all its causes and their advice) so that no advice is cut.
const MAX_MESSAGE: usize = 2000;

/// `text` cut to [`MAX_ECHO`] characters, with `…` when something was cut.
pub(crate) fn clip(text: &str) -> String {
    clip_to(text, MAX_ECHO)
}

fn clip_to(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_string(),
    }
}

/// `text` as a person should read it on a terminal: on one line, what the user gave
/// clipped to [`MAX_ECHO`] characters (every command-line argument it repeats, such as
/// a file name, and every quoted value, between backticks or double quotes as serde and
/// toml quote what they were given), control and format characters escaped, and the
/// whole at most [`MAX_MESSAGE`] characters. The words of `touchc` itself, and so its
/// advice, are never cut.
pub(crate) fn readable(text: &str) -> String {
    let one_line = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let given: Vec<String> = std::env::args_os()
        .skip(1)
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let out = clip_quoted(&clip_given(&one_line, &given), &['`', '"']);
    let total = out.chars().count();
    let out = if total > MAX_MESSAGE {
        format!(
            "{} ({} more characters)",
            clip_to(&out, MAX_MESSAGE),
            total - MAX_MESSAGE
        )
    } else {
        out
    };
    escaped(&out)
}

/// `text` with every long command-line argument in `given` (or its value after `=`,
/// as in `--output=FILE`) clipped to [`MAX_ECHO`] characters wherever it appears.
fn clip_given(text: &str, given: &[String]) -> String {
    let mut long: Vec<&str> = given
        .iter()
        .flat_map(|a| [a.as_str(), a.split_once('=').map_or("", |(_, v)| v)])
        .filter(|a| a.chars().count() > MAX_ECHO)
        .collect();
    // The longest first: an argument can hold another (`dir/file` and `dir`).
    long.sort_by_key(|a| std::cmp::Reverse(a.len()));
    let mut out = text.to_string();
    for a in long {
        out = out.replace(a, &clip(a));
    }
    out
}

/// `text` with every piece between a pair of `quotes` clipped to [`MAX_ECHO`].
fn clip_quoted(text: &str, quotes: &[char]) -> String {
    let mut out = String::with_capacity(text.len().min(4 * MAX_MESSAGE));
    let mut rest = text;
    while let Some(open) = rest.find(quotes) {
        let quote = rest[open..].chars().next().unwrap_or('"');
        let inner = &rest[open + quote.len_utf8()..];
        let Some(close) = inner.find(quote) else {
            // A lone quote (in a clipped value, an apostrophe) opens nothing.
            out.push_str(&rest[..open]);
            out.push(quote);
            rest = inner;
            continue;
        };
        out.push_str(&rest[..open]);
        out.push(quote);
        out.push_str(&clip(&inner[..close]));
        out.push(quote);
        rest = &inner[close + quote.len_utf8()..];
    }
    out.push_str(rest);
    out
}

/// Prints a command-line error of clap's (or its help) and returns its exit status:
/// 2 for a usage error, 0 for `--help` and `--version`. The values it quotes are user
/// text, so they are clipped and escaped like every other message.
pub fn parse_error(err: &clap::Error) -> ExitCode {
    if !err.use_stderr() {
        let _ = err.print();
        return ExitCode::SUCCESS;
    }
    let text = err.render().to_string();
    for line in text.trim_end().lines() {
        eprintln!("{}", escaped(&clip_quoted(line, &['\'', '`', '"'])));
    }
    ExitCode::from(u8::try_from(err.exit_code()).unwrap_or(2))
}

/// `text` with control and format characters shown as escapes (`\u{1b}`, `\n`,
/// `\u{202e}`, ...), so that a name or path from a file can neither drive the terminal
/// it is printed on nor reorder the text around it (bidi overrides, invisible marks).
pub(crate) fn escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else if is_format(c) {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// Whether `c` is invisible yet changes how text around it is shown: Unicode's format
/// characters (general category Cf: bidi controls, zero-width marks, the BOM, tags) and
/// the line and paragraph separators.
fn is_format(c: char) -> bool {
    matches!(
        u32::from(c),
        0x00AD
            | 0x0600..=0x0605
            | 0x061C
            | 0x06DD
            | 0x070F
            | 0x0890..=0x0891
            | 0x08E2
            | 0x180E
            | 0x200B..=0x200F
            | 0x2028..=0x202E
            | 0x2060..=0x2064
            | 0x2066..=0x206F
            | 0xFEFF
            | 0xFFF9..=0xFFFB
            | 0x110BD
            | 0x110CD
            | 0x13430..=0x1343F
            | 0x1BCA0..=0x1BCA3
            | 0x1D173..=0x1D17A
            | 0xE0001
            | 0xE0020..=0xE007F
    )
}

/// Prints a warning about `file` on stderr, escaped like every other message.
pub(crate) fn warn(file: &Path, message: &str) {
    eprintln!(
        "touchc: warning: {}",
        readable(&format!("{}: {message}", input_name(file)))
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line adds the flag to try to the library's account of the error, in
    /// the words `touchc` has always printed, however the error was wrapped.
    #[test]
    fn errors_a_flag_puts_right_name_the_flag() {
        use touchc_input::recording::RecordingError;
        use touchc_pipeline::compile::CompileError;
        use touchc_rendering::condition::LimitViolation;
        use touchc_tracking::track::TrackError;
        let thermal = LimitViolation::Thermal {
            channel: 5,
            sample: 30_000,
            bucket_a2s: 30.5,
            budget_a2s: 30.0,
        };
        let err =
            anyhow::Error::new(CompileError::Limits(thermal)).context("hold.npy: cannot compile");
        assert_eq!(
            message(&err),
            "hold.npy: cannot compile: the signal breaks the safety limits: channel 5, sample \
             30000: thermal load 30.5 A^2 s exceeds 30 A^2 s (use --fit to scale it down)"
        );
        let dense = || TrackError::TooDense {
            detections: 9,
            limit: 40,
        };
        let want = "the scene is too dense to track: 9 detections would link into more than 40 \
                    edges; check the tare, or narrow the link gate with --max-speed-mm-s";
        let tracked = anyhow::Error::new(dense()).context("a.npy: cannot track");
        assert_eq!(message(&tracked), format!("a.npy: cannot track: {want}"));
        let compiled =
            anyhow::Error::new(CompileError::Track(dense())).context("a.npy: cannot compile");
        assert_eq!(message(&compiled), format!("a.npy: cannot compile: {want}"));
        let short = || RecordingError::TooShort {
            name: "short.npy".into(),
            frames: 30,
            tare: 20,
            min: 41,
        };
        let want = "short.npy: 30 frame(s) is too short: the tare window (20 frames) and the \
                    trim at each end need at least 41 frames (input.tare_s, input.trim_s)";
        for err in [
            anyhow::Error::new(short()),
            anyhow::Error::new(CompileError::Recording(short())),
        ] {
            assert_eq!(message(&err), want);
        }
        let big = anyhow::Error::new(RecordingError::MemberTooLarge {
            name: "big.npz".into(),
            entry: "pressure.npy".into(),
            needed: 1 << 40,
            budget: 1 << 29,
        });
        assert_eq!(
            message(&big),
            "big.npz: entry \"pressure.npy\" needs 1099511627776 bytes decompressed, more than \
             the 536870912 bytes an archive entry may take (an archive's sizes can claim far \
             more than its file holds); save the array as a .npy file instead"
        );
    }

    #[test]
    fn a_message_is_one_line_with_its_quoted_values_clipped() {
        let long = "A".repeat(1000);
        let text = format!("bad value `{long}`\nin `input.baseline`\n");
        let shown = readable(&text);
        assert_eq!(
            shown,
            format!("bad value `{}…`; in `input.baseline`", "A".repeat(MAX_ECHO))
        );
        // A lone quote does not stop the clipping of the pairs after it.
        let text = format!("--set x=\"{}…: unknown `{long}`", "B".repeat(10));
        assert!(!readable(&text).contains(&"A".repeat(MAX_ECHO + 1)));
    }

    #[test]
    fn a_long_argument_is_clipped_wherever_it_appears_and_the_advice_is_whole() {
        let dir = "d".repeat(300);
        let path = format!("{dir}/x.npy");
        let advice = "try a finer lattice (--set detect.split.spacing_cells=1)";
        let text = format!("{path}: {}; {advice}", "touch is lost ".repeat(30));
        let given = [path.clone(), format!("--output={dir}/y.touch"), "-o".into()];
        let shown = clip_given(&text, &given);
        assert!(
            shown.starts_with(&format!("{}…", &path[..MAX_ECHO])),
            "{shown}"
        );
        assert!(shown.ends_with(advice), "{shown}");
        let shown = clip_given(&format!("cannot write {dir}/y.touch"), &given);
        assert_eq!(shown, format!("cannot write {}…", &dir[..MAX_ECHO]));
    }

    #[test]
    fn a_message_is_at_most_a_few_lines_long() {
        let shown = readable(&"word ".repeat(1000));
        assert!(shown.chars().count() < MAX_MESSAGE + 40, "{shown}");
        assert!(shown.ends_with("more characters)"), "{shown}");
    }

    #[test]
    fn control_and_format_characters_are_escaped() {
        assert_eq!(escaped("a\u{1b}[31mb"), "a\\u{1b}[31mb");
        assert_eq!(escaped("\u{202e}kcab"), "\\u{202e}kcab");
        assert_eq!(
            escaped("zero\u{200b}width\u{feff}"),
            "zero\\u{200b}width\\u{feff}"
        );
        // Letters, emoji and their variation selectors are text.
        assert_eq!(escaped("café ❤️ 触"), "café ❤️ 触");
    }
}
