//! Subcommand bodies of the `touchc` binary, one module each; shared helpers live here.

pub mod track;

use std::path::Path;

use anyhow::Context;
use touchc::config::Config;

/// Reads a TOML config, or the paper preset when no file is given.
pub fn load_config(path: Option<&Path>) -> anyhow::Result<Config> {
    match path {
        None => Ok(Config::default()),
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read config", p.display()))?;
            toml::from_str(&text).with_context(|| format!("{}: invalid config", p.display()))
        }
    }
}
