//! A config laid in layers, the one meaning of an override wherever it comes from: a
//! [`Preset`], then the keys of config files, then `SECTION.KEY=VALUE` assignments, then
//! typed knob settings, each over the one before, merged as TOML and validated once at
//! the end into a [`ValidConfig`].
//!
//! The layers are merged as TOML rather than as structs so that a file or an assignment
//! gives only the keys it changes and the rest keep the preset's values, including
//! inside an optional table (`detect.split`) the preset has. A key of a table the preset
//! leaves out cannot be given alone (the table's other keys have nothing to keep), so
//! [`Layers::where_it_applies`] leaves such assignments out and names the tables and the
//! keys that would turn them on.

use super::{Config, ConfigError, Knob, Preset, ValidConfig};

/// A knob's value as a typed override, the last layer (what a command line's knob flags
/// give).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setting {
    /// A whole number.
    Count(usize),
    /// A real number.
    Real(f64),
    /// The optional table that holds the knob removed (a coarse-to-fine search off).
    Off,
}

/// An assignment into a table that the preset leaves out and [`Preset::default`] has.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OffTable {
    /// Which assignment, counted from 0 in the order given.
    pub index: usize,
    /// The assignment as given.
    pub assignment: String,
    /// The table, dotted (`detect.split`).
    pub table: String,
    /// The table's keys under [`Preset::default`]: what turns it on.
    pub keys: Vec<String>,
}

/// The layers of a config, built up and then resolved by [`Layers::build`].
///
/// # Example
/// ```
/// use touchc_model::config::{Knob, Layers, Preset, Setting};
/// let config = Layers::new(Preset::Paper)
///     .file("mine.toml", "[detect]\nsigma_k = 1.5\n")
///     .set("detect.sigma_k=2.0")
///     .knob(Knob::PreprocessUpsample, Setting::Count(4))
///     .build()
///     .unwrap();
/// // The assignment is laid over the file, and the knob over both.
/// assert_eq!(config.detect.sigma_k, 2.0);
/// assert_eq!(config.preprocess.upsample, 4);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Layers {
    preset: Preset,
    /// Config files, each its name (for errors) and its text.
    files: Vec<(String, String)>,
    /// `SECTION.KEY=VALUE` assignments, the value in TOML syntax.
    assignments: Vec<String>,
    /// Knob settings, the last one of a knob winning.
    knobs: Vec<(Knob, Setting)>,
}

impl Layers {
    /// The parameters of `preset` with nothing over them.
    pub fn new(preset: Preset) -> Self {
        Layers {
            preset,
            files: Vec::new(),
            assignments: Vec::new(),
            knobs: Vec::new(),
        }
    }

    /// The preset under the layers.
    pub fn preset(&self) -> Preset {
        self.preset
    }

    /// The same layers over `preset` instead.
    #[must_use]
    pub fn on(mut self, preset: Preset) -> Self {
        self.preset = preset;
        self
    }

    /// Adds a config file's keys (TOML `text`; `name` names it in errors) over the
    /// preset and the files before; keys it lacks keep their values.
    #[must_use]
    pub fn file(mut self, name: impl Into<String>, text: impl Into<String>) -> Self {
        self.files.push((name.into(), text.into()));
        self
    }

    /// Adds a `SECTION.KEY=VALUE` assignment (the value in TOML syntax, the key dotted
    /// below its section: `track.regions.seed_psi=0.1`) over the files.
    #[must_use]
    pub fn set(mut self, assignment: impl Into<String>) -> Self {
        self.assignments.push(assignment.into());
        self
    }

    /// [`Layers::set`] for each of `assignments`, in order.
    #[must_use]
    pub fn sets<S: Into<String>>(self, assignments: impl IntoIterator<Item = S>) -> Self {
        assignments.into_iter().fold(self, Layers::set)
    }

    /// Sets `knob` over the assignments (a later setting of the same knob wins).
    #[must_use]
    pub fn knob(mut self, knob: Knob, setting: Setting) -> Self {
        self.knobs.push((knob, setting));
        self
    }

    /// The assignments into a table the preset leaves out and [`Preset::default`] has
    /// (see the module docs).
    fn off_tables(&self) -> Vec<OffTable> {
        let (Ok(base), Ok(full)) = (
            toml::Table::try_from(Config::preset(self.preset)),
            toml::Table::try_from(Config::preset(Preset::default())),
        ) else {
            return Vec::new();
        };
        self.assignments
            .iter()
            .enumerate()
            .filter_map(|(index, text)| off_table(&base, &full, text).map(|t| (index, t)))
            .map(|(index, (table, keys))| OffTable {
                index,
                assignment: self.assignments[index].clone(),
                table,
                keys,
            })
            .collect()
    }

    /// These layers without the assignments into tables the preset leaves out (so one
    /// set of assignments can be laid over several presets), and those left out.
    #[must_use]
    pub fn where_it_applies(mut self) -> (Self, Vec<OffTable>) {
        let off = self.off_tables();
        let mut index = 0;
        self.assignments.retain(|_| {
            index += 1;
            !off.iter().any(|t| t.index == index - 1)
        });
        (self, off)
    }

    /// The config of these layers, validated: the first layer in error is the error
    /// (a file that does not parse or holds a key the config lacks, an assignment that
    /// is not `SECTION.KEY=VALUE` or whose value is not TOML), then the merged keys
    /// against the config's fields, then every knob against its range.
    pub fn build(&self) -> Result<ValidConfig, ConfigError> {
        let base = Config::preset(self.preset);
        if self.files.is_empty() && self.assignments.is_empty() && self.knobs.is_empty() {
            return base.validated();
        }
        let mut table = toml::Table::try_from(&base).map_err(|e| ConfigError::Preset {
            preset: self.preset,
            message: e.to_string(),
        })?;
        for (name, text) in &self.files {
            let file = |source| ConfigError::File {
                name: name.clone(),
                source: Box::new(source),
            };
            let over: toml::Table = toml::from_str(text).map_err(file)?;
            merge(&mut table, over);
            // A file's own mistakes are named by the file.
            from_table(table.clone()).map_err(file)?;
        }
        for assignment in &self.assignments {
            merge(&mut table, parse_assignment(assignment)?);
        }
        for &(knob, setting) in &self.knobs {
            apply(&mut table, knob, setting);
        }
        let config = from_table(table).map_err(|source| ConfigError::Keys {
            assignments: self.assignments.clone(),
            off: self.off_tables(),
            preset: self.preset,
            source: Box::new(source),
        })?;
        config.validated()
    }
}

impl Config {
    /// This config, checked by [`Config::validate`].
    pub fn validated(self) -> Result<ValidConfig, ConfigError> {
        self.validate()?;
        Ok(ValidConfig::checked(self))
    }
}

/// A config read from its TOML image (the keys checked against the fields).
fn from_table(table: toml::Table) -> Result<Config, toml::de::Error> {
    table.try_into()
}

/// `SECTION.KEY=VALUE` as the TOML table it writes.
fn parse_assignment(assignment: &str) -> Result<toml::Table, ConfigError> {
    let syntax = || ConfigError::AssignmentSyntax {
        assignment: assignment.to_string(),
    };
    let (key, value) = assignment.split_once('=').ok_or_else(syntax)?;
    let (section, field) = key.trim().split_once('.').ok_or_else(syntax)?;
    let doc = format!("[{section}]\n{field} = {value}\n");
    toml::from_str(&doc).map_err(|source| ConfigError::AssignmentValue {
        assignment: assignment.to_string(),
        source: Box::new(source),
    })
}

/// For an assignment into a table `base` leaves out and `full` has: the table, dotted,
/// and its keys in `full`.
fn off_table(
    base: &toml::Table,
    full: &toml::Table,
    assignment: &str,
) -> Option<(String, Vec<String>)> {
    let (key, _) = assignment.split_once('=')?;
    let path: Vec<&str> = key.trim().split('.').collect();
    let (mut here, mut there) = (Some(base), Some(full));
    for depth in 1..path.len() {
        let name = path[depth - 1];
        here = here
            .and_then(|t| t.get(name))
            .and_then(toml::Value::as_table);
        there = there
            .and_then(|t| t.get(name))
            .and_then(toml::Value::as_table);
        if let (None, Some(table)) = (here, there) {
            return Some((path[..depth].join("."), table.keys().cloned().collect()));
        }
    }
    None
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

/// Writes `setting` of `knob` into `table`, a config's TOML image: the value (its
/// optional table created if absent), or the knob's table removed.
fn apply(table: &mut toml::Table, knob: Knob, setting: Setting) {
    let mut parts: Vec<&str> = std::iter::once(knob.section())
        .chain(knob.key().split('.'))
        .collect();
    if setting == Setting::Off {
        // The key's own table goes, not the key alone.
        parts.pop();
    }
    let Some(last) = parts.pop() else { return };
    let mut t = table;
    for part in parts {
        let entry = t
            .entry(part)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let Some(inner) = entry.as_table_mut() else {
            return;
        };
        t = inner;
    }
    let value = match setting {
        Setting::Count(n) => toml::Value::Integer(i64::try_from(n).unwrap_or(i64::MAX)),
        Setting::Real(v) => toml::Value::Float(v),
        Setting::Off => {
            t.remove(last);
            return;
        }
    };
    t.insert(last.to_string(), value);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{CoarseToFine, Unit};

    /// Each layer is laid over the one before: file over preset, a later file over an
    /// earlier one, assignment over file, knob over assignment; a key no layer gives
    /// keeps the preset's value.
    #[test]
    fn each_layer_wins_over_the_one_before() {
        let paper = Config::preset(Preset::Paper);
        let config = Layers::new(Preset::Paper)
            .file(
                "a.toml",
                "[detect]\nsigma_k = 1.0\n[track]\nentry_cost = 3.0\n",
            )
            .file("b.toml", "[detect]\nsigma_k = 1.5\n")
            .set("track.entry_cost=4.0")
            .set("preprocess.upsample = 5")
            .knob(Knob::PreprocessUpsample, Setting::Count(3))
            .knob(Knob::PreprocessUpsample, Setting::Count(6))
            .build()
            .unwrap();
        assert_eq!(config.detect.sigma_k, 1.5);
        assert_eq!(config.track.entry_cost, 4.0);
        assert_eq!(config.preprocess.upsample, 6);
        assert_eq!(config.track.exit_cost, paper.track.exit_cost);
        let mut want = paper;
        want.detect.sigma_k = 1.5;
        want.track.entry_cost = 4.0;
        want.preprocess.upsample = 6;
        assert_eq!(config.into_config(), want);
        // No layer at all: the preset itself.
        assert_eq!(
            Layers::new(Preset::Fast).build(),
            Ok(ValidConfig::preset(Preset::Fast))
        );
    }

    /// A key below an optional table is set within it; a knob `Off` removes its table,
    /// and a setting creates the table it is in.
    #[test]
    fn optional_tables_take_keys_and_go_off() {
        let fast = Layers::new(Preset::Fast)
            .knob(Knob::PlacementCoarseToFineStride, Setting::Off)
            .build()
            .unwrap();
        assert_eq!(fast.placement.coarse_to_fine, None);
        let paper = Layers::new(Preset::Paper)
            .knob(Knob::PlacementCoarseToFineStride, Setting::Count(3))
            .knob(Knob::PlacementCoarseToFineKeep, Setting::Count(16))
            .build()
            .unwrap();
        assert_eq!(
            paper.placement.coarse_to_fine,
            Some(CoarseToFine {
                stride: 3,
                keep: 16
            })
        );
        let touch = Layers::new(Preset::Touch)
            .set("track.regions.seed_psi=0.1")
            .build()
            .unwrap();
        assert_eq!(touch.track.regions.map(|r| r.seed_psi), Some(0.1));
    }

    /// An assignment without `=` or without a section is a syntax error, one whose value
    /// is not TOML a value error; both name the assignment as given.
    #[test]
    fn a_malformed_assignment_is_refused_as_given() {
        for bad in ["no-equals-sign", "sigma_k=1.5", "=1"] {
            assert_eq!(
                Layers::new(Preset::Touch).set(bad).build(),
                Err(ConfigError::AssignmentSyntax {
                    assignment: bad.into()
                }),
                "{bad}"
            );
        }
        for bad in ["detect.sigma_k=", "detect.sigma_k=one", "detect.sigma_k=[1"] {
            match Layers::new(Preset::Touch).set(bad).build() {
                Err(ConfigError::AssignmentValue { assignment, .. }) => {
                    assert_eq!(assignment, bad)
                }
                other => panic!("{bad}: {other:?}"),
            }
        }
        let err = Layers::new(Preset::Touch).set("x").build().unwrap_err();
        assert_eq!(err.to_string(), "`x`: expected SECTION.KEY=VALUE");
    }

    /// A key the config lacks is refused: in a file, as that file's; in an assignment,
    /// naming every assignment given; a value of the wrong kind likewise.
    #[test]
    fn an_unknown_key_is_refused_by_its_layer() {
        match Layers::new(Preset::Touch)
            .file("mine.toml", "[track]\nmax_speed = 5\n")
            .build()
        {
            Err(ConfigError::File { name, source }) => {
                assert_eq!(name, "mine.toml");
                assert!(source.to_string().contains("unknown field `max_speed`"));
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            Layers::new(Preset::Touch)
                .file("bad.toml", "[track")
                .build(),
            Err(ConfigError::File { .. })
        ));
        let err = Layers::new(Preset::Touch)
            .set("detect.sigma_k=1.5")
            .set("track.max_speed=5")
            .build()
            .unwrap_err();
        assert!(
            matches!(&err, ConfigError::Keys { assignments, off, .. }
                if assignments.len() == 2 && off.is_empty()),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "`detect.sigma_k=1.5`, `track.max_speed=5`: invalid parameter"
        );
        let err = std::error::Error::source(&err).unwrap().to_string();
        assert!(
            err.contains("unknown field `max_speed`") && err.contains("max_speed_mm_s"),
            "{err}"
        );
        assert!(matches!(
            Layers::new(Preset::Touch)
                .set("detect.sigma_k=\"high\"")
                .build(),
            Err(ConfigError::Keys { .. })
        ));
    }

    /// The merged config is validated: a knob out of range in any layer is refused as
    /// that knob.
    #[test]
    fn the_merged_config_is_validated() {
        assert_eq!(
            Layers::new(Preset::Touch)
                .set("detect.sigma_k=1e308")
                .build(),
            Err(ConfigError::OutOfRange {
                knob: Knob::DetectSigmaK,
                value: 1e308,
                min: -10.0,
                max: 10.0,
                unit: Unit::StandardDeviations,
            })
        );
        assert!(matches!(
            Layers::new(Preset::Touch)
                .knob(Knob::PreprocessUpsample, Setting::Count(0))
                .build(),
            Err(ConfigError::CountOutOfRange {
                knob: Knob::PreprocessUpsample,
                ..
            })
        ));
    }

    /// A key of a table the preset leaves out (`paper` has no contact regions) is named
    /// as off, with the table's keys; [`Layers::where_it_applies`] drops it and keeps the
    /// rest in order.
    #[test]
    fn a_key_of_a_table_the_preset_leaves_out_is_off() {
        let layers = Layers::new(Preset::Paper)
            .set("detect.sigma_k=1.5")
            .set("track.regions.seed_psi=0.1")
            .set("track.entry_cost=4");
        let off = layers.off_tables();
        assert_eq!(off.len(), 1);
        assert_eq!(off[0].index, 1);
        assert_eq!(off[0].assignment, "track.regions.seed_psi=0.1");
        assert_eq!(off[0].table, "track.regions");
        assert!(off[0].keys.contains(&"footprint_psi".to_string()));
        match layers.build() {
            Err(ConfigError::Keys {
                off: named, source, ..
            }) => {
                assert_eq!(named, off);
                assert!(source.to_string().contains("missing field `footprint_psi`"));
            }
            other => panic!("{other:?}"),
        }
        let (kept, left_out) = layers.clone().where_it_applies();
        assert_eq!(left_out, off);
        let config = kept.build().unwrap();
        assert_eq!((config.detect.sigma_k, config.track.entry_cost), (1.5, 4.0));
        assert_eq!(config.track.regions, None);
        // Under a preset that has the table, nothing is off.
        assert!(layers.on(Preset::Touch).off_tables().is_empty());
    }
}
