//! A config laid in layers: the preset, then the keys of a `--config` file, then the
//! `--set SECTION.KEY=VALUE` assignments, then the knob flags, merged as TOML and
//! validated once at the end.

use std::path::Path;

use anyhow::Context;
use touchc_model::config::{Config, Preset};

use super::Knobs;

/// `preset`, with the keys of the TOML file `path` (if any), then the `SECTION.KEY=VALUE`
/// assignments of `sets`, then the knob flags, laid over it.
pub(super) fn layered(
    preset: Preset,
    path: Option<&Path>,
    sets: &[String],
    knobs: &Knobs,
) -> anyhow::Result<Config> {
    let base = Config::preset(preset);
    if path.is_none() && sets.is_empty() && knobs.0.is_empty() {
        return Ok(base);
    }
    let mut table = toml::Table::try_from(&base).context("cannot serialise the preset")?;
    let mut off: Vec<String> = off_tables(&table, sets)
        .iter()
        .map(|t| t.explain(preset))
        .collect();
    off.sort();
    off.dedup();
    if let Some(p) = path {
        let text = crate::cli::input::read_text(p, crate::cli::input::MAX_TEXT_BYTES)
            .with_context(|| format!("{}: cannot read config", p.display()))?;
        let over: toml::Table =
            toml::from_str(&text).with_context(|| format!("{}: invalid config", p.display()))?;
        merge(&mut table, over);
        let checked: Result<Config, _> = table.clone().try_into();
        checked.with_context(|| format!("{}: invalid config", p.display()))?;
    }
    for set in sets {
        let (key, value) = set.split_once('=').with_context(|| {
            format!(
                "--set {}: expected SECTION.KEY=VALUE",
                crate::cli::report::clip(set)
            )
        })?;
        let (section, field) = key.trim().split_once('.').with_context(|| {
            format!(
                "--set {}: expected SECTION.KEY=VALUE",
                crate::cli::report::clip(set)
            )
        })?;
        let doc = format!("[{section}]\n{field} = {value}\n");
        let over: toml::Table = toml::from_str(&doc).with_context(|| {
            format!("--set {}: not a TOML value", crate::cli::report::clip(set))
        })?;
        merge(&mut table, over);
    }
    for assignment in &knobs.0 {
        assignment.apply(&mut table);
    }
    let config: anyhow::Result<Config> = table.try_into().with_context(|| {
        if sets.is_empty() {
            "invalid parameter".to_string()
        } else {
            let sets: Vec<String> = sets.iter().map(|s| crate::cli::report::clip(s)).collect();
            format!("--set {}: invalid parameter", sets.join(" --set "))
        }
    });
    let config = match (config, off.is_empty()) {
        (Ok(config), _) => config,
        (Err(e), true) => return Err(e),
        (Err(e), false) => {
            anyhow::bail!("{}; {}", crate::cli::report::message(&e), off.join("; "))
        }
    };
    config
        .validate()
        .map_err(|e| anyhow::Error::new(e).context("config"))?;
    Ok(config)
}

/// A `--set` into a table a preset leaves out and the default preset has.
pub(super) struct OffTable {
    /// Which `--set`.
    pub(super) set: usize,
    /// The table, dotted (`detect.split`).
    pub(super) table: String,
    /// The table's keys under the default preset.
    keys: Vec<String>,
}

impl OffTable {
    /// Why the `--set` cannot be taken alone under `preset`, and what would do.
    fn explain(&self, preset: Preset) -> String {
        format!(
            "`{}` is off under --preset {}: set its keys ({}) or start from --preset {}",
            self.table,
            preset.name(),
            self.keys.join(", "),
            Preset::default().name()
        )
    }
}

/// For each `--set` into a table `preset` leaves out (its table `base`) and the default
/// preset has: the table and the keys that turn it on. A lone key cannot: the table's
/// other keys have no value to keep.
pub(super) fn off_tables(base: &toml::Table, sets: &[String]) -> Vec<OffTable> {
    let Ok(full) = toml::Table::try_from(Config::preset(Preset::default())) else {
        return Vec::new();
    };
    let mut off = Vec::new();
    for (set, text) in sets.iter().enumerate() {
        let Some((key, _)) = text.split_once('=') else {
            continue;
        };
        let path: Vec<&str> = key.trim().split('.').collect();
        let (mut here, mut there) = (Some(base), Some(&full));
        for depth in 1..path.len() {
            let name = path[depth - 1];
            here = here
                .and_then(|t| t.get(name))
                .and_then(toml::Value::as_table);
            there = there
                .and_then(|t| t.get(name))
                .and_then(toml::Value::as_table);
            if let (None, Some(table)) = (here, there) {
                off.push(OffTable {
                    set,
                    table: path[..depth].join("."),
                    keys: table.keys().cloned().collect(),
                });
                break;
            }
        }
    }
    off
}

/// Lays `over` onto `base`, table by table.
fn merge(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}
