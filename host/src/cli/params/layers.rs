//! The command line's flags as config layers ([`touchc_model::config::Layers`]): the
//! preset, the `--config` file read, the `--set`s and the knob flags.

use std::path::Path;

use anyhow::Context;
use touchc_model::config::{Layers, Preset};

use super::ConfigArgs;
use crate::cli::report::{message, usage};

impl ConfigArgs {
    /// The layers these flags give over `preset`: the `--config` file read, the
    /// `--set`s and the knob flags.
    pub(super) fn layers(&self, preset: Preset) -> anyhow::Result<Layers> {
        let mut layers = Layers::new(preset);
        if let Some(path) = &self.config {
            layers = layers.file(path.display().to_string(), read(path)?);
        }
        Ok(self
            .knobs
            .0
            .iter()
            .fold(layers.sets(&self.set), |l, &(k, s)| l.knob(k, s)))
    }
}

/// The text of the `--config` file at `path`; an error is a usage error.
fn read(path: &Path) -> anyhow::Result<String> {
    crate::cli::input::read_text(path, crate::cli::input::MAX_TEXT_BYTES)
        .with_context(|| format!("{}: cannot read config", path.display()))
        .map_err(|e| usage(message(&e)))
}
