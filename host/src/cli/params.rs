//! The algorithm parameters on the command line, shared by every command that runs the
//! pipeline (`compile`, `track`, `preview`, `trade`): `--preset`, `--config FILE`,
//! `--set SECTION.KEY=VALUE`, then one flag per common knob, each layer overriding the
//! one before, and the recording's `--rate` and `--pitch-mm`.
//!
//! The knob flags are one table ([`KNOBS`]) of config keys: each flag is a typed
//! shorthand for a `--set`, laid over the same TOML image of the config, and its help
//! prints the key's value in [`Config::default`], so neither a default nor a field is
//! written twice.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::Context;
use clap::{Arg, ArgMatches, FromArgMatches};
use touchc::config::{CoarseToFine, Config, MetadataOverrides, Preset};
use touchc::display::Shortest;

/// `--help` heading of the recording's sampling flags.
pub const INPUT_AND_SENSOR: &str = "Input and sensor";
/// `--help` heading of the parameter flags.
pub const PRESET_AND_KNOBS: &str = "Preset and knobs";
/// `--help` heading of what a command writes.
pub const OUTPUT: &str = "Output";

/// Parameter and sampling flags: the same set on every command that runs the pipeline.
/// Every knob is physical (its unit in its name); a flag not given keeps the preset's
/// value.
#[derive(Debug, Clone, clap::Args)]
pub struct ConfigArgs {
    #[arg(
        long,
        value_name = "HZ",
        help = sampling_help("The recording's frame rate, Hz, 1 to 1000", "rate_hz"),
        help_heading = INPUT_AND_SENSOR
    )]
    pub rate: Option<f64>,
    #[arg(
        long,
        value_name = "MM",
        help = sampling_help("The sensor's cell pitch, mm, 0.1 to 100", "pitch_mm"),
        help_heading = INPUT_AND_SENSOR
    )]
    pub pitch_mm: Option<f64>,
    #[arg(
        long,
        value_parser = super::help::PlainEnum::<Preset>::new(),
        value_name = "PRESET",
        help = preset_help(),
        help_heading = PRESET_AND_KNOBS
    )]
    pub preset: Option<Preset>,
    /// TOML file overriding the preset's parameters (missing keys keep the preset's).
    #[arg(long, help_heading = PRESET_AND_KNOBS)]
    pub config: Option<PathBuf>,
    /// Any parameter, as `SECTION.KEY=VALUE` in TOML syntax (for example
    /// `detect.sigma_k=1.5` or `input.baseline="robust"`); may be repeated. Applied
    /// after the config file, before the knob flags.
    #[arg(long = "set", value_name = "SECTION.KEY=VALUE", help_heading = PRESET_AND_KNOBS)]
    pub set: Vec<String>,
    /// The knob flags of [`KNOBS`].
    #[command(flatten)]
    pub knobs: Knobs,
}

/// `--preset`'s help, naming the real default ([`Preset::default`], whose parameters
/// are [`Config::default`]).
fn preset_help() -> String {
    format!(
        "Parameter preset: `touch` (real touch: fast strokes, brief taps, flat hands, \
         flicker, touch at the start), `paper` (the published algorithm, bit for bit), \
         `fast` (x4 upsampling, coarse-to-fine placement search), `exact` (a \
         60,060-transform grid) [default: {}]",
        Preset::default().name()
    )
}

/// Help of `--rate` and `--pitch-mm`: the file's value wins, else the config's `key`.
fn sampling_help(what: &str, key: &str) -> String {
    let key = format!("input.{key}");
    format!(
        "{what} (default: the file's, else `{key}`, {})",
        default_of(&key).unwrap_or_else(|| "?".into())
    )
}

/// How a knob flag's value is read and written into the config.
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// A whole number.
    Count,
    /// A real number.
    Real,
    /// `X,Y` or `N`: the two keys `KEY_x` and `KEY_y`.
    Grid,
    /// `STRIDE,KEEP` or `off` (the key absent).
    Search,
}

/// One knob flag: `--flag` sets the config key `section.key`.
#[derive(Debug)]
pub struct Knob {
    flag: &'static str,
    section: &'static str,
    key: &'static str,
    kind: Kind,
    value_name: &'static str,
    help: &'static str,
}

/// The knobs with a flag of their own; every other key is reached with `--set`.
const KNOBS: &[Knob] = &[
    Knob {
        flag: "upsample",
        section: "preprocess",
        key: "upsample",
        kind: Kind::Count,
        value_name: "K",
        help: "Upsampling factor k. Blur and link gate are in mm and mm/s, so they keep \
               their physical size",
    },
    Knob {
        flag: "blur-sigma-mm",
        section: "preprocess",
        key: "blur_sigma_mm",
        kind: Kind::Real,
        value_name: "MM",
        help: "Gaussian blur sigma, mm",
    },
    Knob {
        flag: "entry-cost",
        section: "track",
        key: "entry_cost",
        kind: Kind::Real,
        value_name: "COST",
        help: "Cost of starting a trajectory, -ln P_entr",
    },
    Knob {
        flag: "exit-cost",
        section: "track",
        key: "exit_cost",
        kind: Kind::Real,
        value_name: "COST",
        help: "Cost of ending a trajectory, -ln P_exit",
    },
    Knob {
        flag: "max-speed-mm-s",
        section: "track",
        key: "max_speed_mm_s",
        kind: Kind::Real,
        value_name: "MM_S",
        help: "Link gate: the fastest a contact may move between frames, mm/s",
    },
    Knob {
        flag: "max-trajectories",
        section: "track",
        key: "max_trajectories",
        kind: Kind::Count,
        value_name: "N",
        help: "Most trajectories",
    },
    Knob {
        flag: "grid",
        section: "placement",
        key: "grid",
        kind: Kind::Grid,
        value_name: "X,Y",
        help: "Transform grid `X,Y` (x points, y points) or `N` for `N,N`",
    },
    Knob {
        flag: "coarse-to-fine",
        section: "placement",
        key: "coarse_to_fine",
        kind: Kind::Search,
        value_name: "STRIDE,KEEP",
        help: "Coarse-to-fine placement search `STRIDE,KEEP` (fast: 2,32), or `off`",
    },
    Knob {
        flag: "centre-bonus",
        section: "placement",
        key: "centre_bonus",
        kind: Kind::Real,
        value_name: "B",
        help: "Workspace centre bonus b of D = w (1 + b - b d^2 / r^2)",
    },
    Knob {
        flag: "lowpass-hz",
        section: "signal",
        key: "lowpass_hz",
        kind: Kind::Real,
        value_name: "HZ",
        help: "Low-pass cut-off, Hz (below half the recording's rate)",
    },
];

/// [`Config::default`] as TOML, the source of every printed default.
fn default_table() -> &'static toml::Table {
    static TABLE: OnceLock<toml::Table> = OnceLock::new();
    TABLE.get_or_init(|| toml::Table::try_from(Config::default()).unwrap_or_default())
}

/// The value of `section.key` in [`Config::default`], as a flag would write it.
fn default_of(path: &str) -> Option<String> {
    let (section, key) = path.split_once('.')?;
    let section = default_table().get(section)?.as_table()?;
    Some(plain(section.get(key)?))
}

/// A TOML number as a person types it (`2000`, not `2000.0`).
fn plain(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(f) => f.to_string(),
        other => other.to_string(),
    }
}

impl Knob {
    /// The key's value in [`Config::default`], in the flag's own syntax.
    fn default_text(&self) -> String {
        let section = default_table()
            .get(self.section)
            .and_then(toml::Value::as_table);
        let get = |key: &str| section.and_then(|s| s.get(key)).map(plain);
        let text = match self.kind {
            Kind::Count | Kind::Real => get(self.key),
            Kind::Grid => get(&format!("{}_x", self.key))
                .zip(get(&format!("{}_y", self.key)))
                .map(|(x, y)| format!("{x},{y}")),
            // An absent search is `off`.
            Kind::Search => Some(
                match section
                    .and_then(|s| s.get(self.key))
                    .and_then(toml::Value::as_table)
                {
                    Some(t) => {
                        let get = |k: &str| t.get(k).map_or_else(|| "?".into(), plain);
                        format!("{},{}", get("stride"), get("keep"))
                    }
                    None => "off".into(),
                },
            ),
        };
        text.unwrap_or_else(|| "?".into())
    }

    fn arg(&self) -> Arg {
        let arg = Arg::new(self.flag)
            .long(self.flag)
            .value_name(self.value_name)
            .help_heading(PRESET_AND_KNOBS)
            .help(format!("{} [default: {}]", self.help, self.default_text()));
        match self.kind {
            Kind::Count => arg.value_parser(clap::value_parser!(usize)),
            Kind::Real => arg.value_parser(clap::value_parser!(f64)),
            Kind::Grid => arg.value_parser(parse_grid),
            Kind::Search => arg.value_parser(parse_coarse_to_fine),
        }
    }

    /// The `(key, value)` pairs the flag's value in `m` writes into its section, `None`
    /// as a value removing the key.
    fn assignments(&self, m: &ArgMatches) -> Vec<(String, Option<toml::Value>)> {
        let int = |n: usize| toml::Value::Integer(i64::try_from(n).unwrap_or(i64::MAX));
        let key = self.key.to_string();
        match self.kind {
            Kind::Count => m
                .get_one::<usize>(self.flag)
                .map(|&n| vec![(key, Some(int(n)))]),
            Kind::Real => m
                .get_one::<f64>(self.flag)
                .map(|&v| vec![(key, Some(toml::Value::Float(v)))]),
            Kind::Grid => m.get_one::<(usize, usize)>(self.flag).map(|&(x, y)| {
                vec![
                    (format!("{key}_x"), Some(int(x))),
                    (format!("{key}_y"), Some(int(y))),
                ]
            }),
            Kind::Search => m.get_one::<Search>(self.flag).map(|Search(s)| {
                let value = s.map(|s| {
                    let mut t = toml::Table::new();
                    t.insert("stride".into(), int(s.stride));
                    t.insert("keep".into(), int(s.keep));
                    toml::Value::Table(t)
                });
                vec![(key, value)]
            }),
        }
        .unwrap_or_default()
    }
}

/// The knob flags given, as assignments to the config's TOML image.
#[derive(Debug, Clone, Default)]
pub struct Knobs(Vec<(&'static str, String, Option<toml::Value>)>);

impl FromArgMatches for Knobs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut knobs = Knobs::default();
        knobs.update_from_arg_matches(m)?;
        Ok(knobs)
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        for knob in KNOBS {
            for (key, value) in knob.assignments(m) {
                self.0
                    .retain(|(s, k, _)| !(*s == knob.section && *k == key));
                self.0.push((knob.section, key, value));
            }
        }
        Ok(())
    }
}

impl clap::Args for Knobs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        KNOBS.iter().fold(cmd, |cmd, knob| cmd.arg(knob.arg()))
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// The placement search a `--coarse-to-fine` flag asks for.
#[derive(Debug, Clone, Copy)]
struct Search(Option<CoarseToFine>);

impl ConfigArgs {
    /// The config these flags describe, on the preset given (else the default one).
    pub fn resolve(&self) -> anyhow::Result<Config> {
        self.resolve_on(self.preset.unwrap_or_default())
    }

    /// The config these flags describe, laid over `preset` whatever `--preset` says.
    /// Every error is a usage error (exit status 2): the parameters are how the command
    /// was called, the `--config` file included. So are `--rate` and `--pitch-mm`
    /// outside the ranges any recording may have.
    pub fn resolve_on(&self, preset: Preset) -> anyhow::Result<Config> {
        let config = layered(preset, self.config.as_deref(), &self.set, &self.knobs)
            .map_err(|e| super::usage(super::message(&e)))?;
        self.check_sampling()?;
        Ok(config)
    }

    /// `--rate` and `--pitch-mm` against the ranges a recording's own values must meet.
    fn check_sampling(&self) -> anyhow::Result<()> {
        use touchc::input::recording::{PITCH_MM_RANGE, RATE_HZ_RANGE};
        for (flag, value, range, unit) in [
            ("--rate", self.rate, RATE_HZ_RANGE, "Hz"),
            ("--pitch-mm", self.pitch_mm, PITCH_MM_RANGE, "mm"),
        ] {
            if let Some(v) = value.filter(|v| !range.contains(v)) {
                return Err(super::usage(format!(
                    "{flag} {} is out of range: must be {} to {} {unit}",
                    Shortest(v),
                    Shortest(*range.start()),
                    Shortest(*range.end()),
                )));
            }
        }
        Ok(())
    }

    /// The recording's sampling these flags give: over the file's own values (`.npz`
    /// `rate_hz`, `pitch_mm`), which are over the config's.
    pub fn overrides(&self) -> MetadataOverrides {
        MetadataOverrides {
            rate_hz: self.rate,
            pitch_mm: self.pitch_mm,
        }
    }
}

/// `preset`, with the keys of the TOML file `path` (if any), then the `SECTION.KEY=VALUE`
/// assignments of `sets`, then the knob flags, laid over it.
fn layered(
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
    if let Some(p) = path {
        let text = std::fs::read_to_string(p)
            .with_context(|| format!("{}: cannot read config", p.display()))?;
        let over: toml::Table =
            toml::from_str(&text).with_context(|| format!("{}: invalid config", p.display()))?;
        merge(&mut table, over);
        let checked: Result<Config, _> = table.clone().try_into();
        checked.with_context(|| format!("{}: invalid config", p.display()))?;
    }
    for set in sets {
        let (key, value) = set
            .split_once('=')
            .with_context(|| format!("--set {}: expected SECTION.KEY=VALUE", super::clip(set)))?;
        let (section, field) = key
            .trim()
            .split_once('.')
            .with_context(|| format!("--set {}: expected SECTION.KEY=VALUE", super::clip(set)))?;
        let doc = format!("[{section}]\n{field} = {value}\n");
        let over: toml::Table = toml::from_str(&doc)
            .with_context(|| format!("--set {}: not a TOML value", super::clip(set)))?;
        merge(&mut table, over);
    }
    for (section, key, value) in &knobs.0 {
        if let Some(toml::Value::Table(s)) = table.get_mut(*section) {
            match value {
                Some(v) => s.insert(key.clone(), v.clone()),
                None => s.remove(key),
            };
        }
    }
    let config: Config = table.try_into().with_context(|| {
        if sets.is_empty() {
            "invalid parameter".to_string()
        } else {
            let sets: Vec<String> = sets.iter().map(|s| super::clip(s)).collect();
            format!("--set {}: invalid parameter", sets.join(" --set "))
        }
    })?;
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("config: {}", super::config_error::describe(&e)))?;
    Ok(config)
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

fn parse_grid(s: &str) -> Result<(usize, usize), String> {
    let num = |t: &str| {
        t.trim()
            .parse::<usize>()
            .map_err(|e| format!("`{t}` is not a grid size: {e}"))
    };
    match s.split_once(',') {
        Some((x, y)) => Ok((num(x)?, num(y)?)),
        None => num(s).map(|n| (n, n)),
    }
}

fn parse_coarse_to_fine(s: &str) -> Result<Search, String> {
    if s == "off" {
        return Ok(Search(None));
    }
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected STRIDE,KEEP or off, got `{s}`"))?;
    let num = |t: &str| t.trim().parse::<usize>().map_err(|e| format!("`{t}`: {e}"));
    Ok(Search(Some(CoarseToFine {
        stride: num(a)?,
        keep: num(b)?,
    })))
}
