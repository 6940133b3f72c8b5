//! The command line's side of the config layers ([`touchc_model::config::Layers`]): the
//! `--config` file read, and a layer's error in the words of the flag that gave it.

use std::path::Path;

use anyhow::Context;
use touchc_model::config::{ConfigError, OffTable, Preset};

use crate::cli::report::{clip, message, usage};

/// The text of the `--config` file at `path`; an error is a usage error.
pub(super) fn read(path: &Path) -> anyhow::Result<String> {
    crate::cli::input::read_text(path, crate::cli::input::MAX_TEXT_BYTES)
        .with_context(|| format!("{}: cannot read config", path.display()))
        .map_err(|e| usage(message(&e)))
}

/// `e` as a usage error (exit status 2) that names the flag of the layer in error
/// (`--config`'s file, the `--set`s, `--preset`); a knob out of range in its own words.
pub(super) fn words(e: ConfigError) -> anyhow::Error {
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
