//! The algorithm parameters on the command line, shared by every command that runs the
//! pipeline (`compile`, `track`, `preview`, `trade`): `--preset`, `--config FILE`,
//! `--set SECTION.KEY=VALUE`, then one flag per common knob, each layer overriding the
//! one before, and the recording's `--rate` and `--pitch-mm`.
//!
//! The layers mean what [`Layers`] says they mean (the library merges and validates
//! them); this module only reads the flags into layers (`params/layers.rs`), and
//! `cli/report.rs` words the library's errors by the flags. The knob flags are one
//! table ([`KNOBS`]) of config knobs ([`Knob`], whose own table names each knob's
//! section and key once): each flag is a typed shorthand for a `--set` ([`Setting`]),
//! and its help prints the key's value in [`Config::default`], so neither a default nor
//! a field is written twice.

use std::path::PathBuf;
use std::sync::OnceLock;

use clap::{Arg, ArgMatches, FromArgMatches};
use touchc_model::config::{
    CoarseToFine, Config, Knob, Layers, MetadataOverrides, Preset, Setting, ValidConfig,
};
use touchc_model::display::Shortest;

mod layers;

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
        help = sampling_help("The recording's frame rate, Hz, 1 to 1000", Knob::InputRateHz),
        help_heading = INPUT_AND_SENSOR
    )]
    pub rate: Option<f64>,
    #[arg(
        long,
        value_name = "MM",
        help = sampling_help("The sensor's cell pitch, mm, 0.1 to 100", Knob::InputPitchMm),
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

/// Help of `--rate` and `--pitch-mm`: the file's value wins, else the config's `knob`.
fn sampling_help(what: &str, knob: Knob) -> String {
    format!(
        "{what} (default: the file's, else `{knob}`, {})",
        lookup(default_table(), knob).map_or_else(|| "?".into(), plain)
    )
}

/// How a knob flag's value is read, and the knobs of [`touchc_model::config::Knob`]'s table
/// it writes (so a flag names its keys only through that table).
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// A whole number.
    Count(Knob),
    /// A real number.
    Real(Knob),
    /// `X,Y` or `N`: the two knobs `x` and `y`.
    Grid { x: Knob, y: Knob },
    /// `STRIDE,KEEP` or `off` (their table absent).
    Search { stride: Knob, keep: Knob },
}

impl Kind {
    /// The knobs the flag writes.
    fn knobs(self) -> Vec<Knob> {
        match self {
            Kind::Count(k) | Kind::Real(k) => vec![k],
            Kind::Grid { x, y } => vec![x, y],
            Kind::Search { stride, keep } => vec![stride, keep],
        }
    }
}

/// The value of `knob` in `table` (a config's TOML image), found by its section and key.
fn lookup(table: &toml::Table, knob: Knob) -> Option<&toml::Value> {
    let mut v = table.get(knob.section());
    for part in knob.key().split('.') {
        v = v?.as_table()?.get(part);
    }
    v
}

/// One knob flag: `--flag` sets the knobs of its `kind`.
#[derive(Debug)]
pub struct Flag {
    flag: &'static str,
    kind: Kind,
    value_name: &'static str,
    help: &'static str,
}

/// The knobs with a flag of their own; every other key is reached with `--set`.
const KNOBS: &[Flag] = &[
    Flag {
        flag: "upsample",
        kind: Kind::Count(Knob::PreprocessUpsample),
        value_name: "K",
        help: "Upsampling factor k. Blur and link gate are in mm and mm/s, so they keep \
               their physical size",
    },
    Flag {
        flag: "blur-sigma-mm",
        kind: Kind::Real(Knob::PreprocessBlurSigmaMm),
        value_name: "MM",
        help: "Gaussian blur sigma, mm",
    },
    Flag {
        flag: "entry-cost",
        kind: Kind::Real(Knob::TrackEntryCost),
        value_name: "COST",
        help: "Cost of starting a trajectory, -ln P_entr",
    },
    Flag {
        flag: "exit-cost",
        kind: Kind::Real(Knob::TrackExitCost),
        value_name: "COST",
        help: "Cost of ending a trajectory, -ln P_exit",
    },
    Flag {
        flag: "max-speed-mm-s",
        kind: Kind::Real(Knob::TrackMaxSpeedMmS),
        value_name: "MM_S",
        help: "Link gate: the fastest a contact may move between frames, mm/s",
    },
    Flag {
        flag: "max-trajectories",
        kind: Kind::Count(Knob::TrackMaxTrajectories),
        value_name: "N",
        help: "Most trajectories",
    },
    Flag {
        flag: "grid",
        kind: Kind::Grid {
            x: Knob::PlacementGridX,
            y: Knob::PlacementGridY,
        },
        value_name: "X,Y",
        help: "Transform grid `X,Y` (x points, y points) or `N` for `N,N`",
    },
    Flag {
        flag: "coarse-to-fine",
        kind: Kind::Search {
            stride: Knob::PlacementCoarseToFineStride,
            keep: Knob::PlacementCoarseToFineKeep,
        },
        value_name: "STRIDE,KEEP",
        help: "Coarse-to-fine placement search `STRIDE,KEEP` (fast: 2,32), or `off`",
    },
    Flag {
        flag: "centre-bonus",
        kind: Kind::Real(Knob::PlacementCentreBonus),
        value_name: "B",
        help: "Workspace centre bonus b of D = w (1 + b - b d^2 / r^2)",
    },
    Flag {
        flag: "lowpass-hz",
        kind: Kind::Real(Knob::SignalLowpassHz),
        value_name: "HZ",
        help: "Low-pass cut-off, Hz (below half the recording's rate)",
    },
];

/// [`Config::default`] as TOML, the source of every printed default.
fn default_table() -> &'static toml::Table {
    static TABLE: OnceLock<toml::Table> = OnceLock::new();
    TABLE.get_or_init(|| toml::Table::try_from(Config::default()).unwrap_or_default())
}

/// A TOML number as a person types it (`2000`, not `2000.0`).
fn plain(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(f) => f.to_string(),
        other => other.to_string(),
    }
}

impl Flag {
    /// The key's value in [`Config::default`], in the flag's own syntax.
    fn default_text(&self) -> String {
        let get = |k: Knob| lookup(default_table(), k).map(plain);
        let text = match self.kind {
            Kind::Count(k) => get(k),
            Kind::Real(k) => get(k).map(super::input::rounded),
            Kind::Grid { x, y } => get(x).zip(get(y)).map(|(x, y)| format!("{x},{y}")),
            // An absent search is `off`.
            Kind::Search { stride, keep } => Some(
                get(stride)
                    .zip(get(keep))
                    .map_or_else(|| "off".into(), |(s, k)| format!("{s},{k}")),
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
            Kind::Count(_) => arg.value_parser(clap::value_parser!(usize)),
            Kind::Real(_) => arg.value_parser(clap::value_parser!(f64)),
            Kind::Grid { .. } => arg.value_parser(parse_grid),
            Kind::Search { .. } => arg.value_parser(parse_coarse_to_fine),
        }
    }

    /// The knob settings the flag's value in `m` gives.
    fn settings(&self, m: &ArgMatches) -> Vec<(Knob, Setting)> {
        match self.kind {
            Kind::Count(k) => m
                .get_one::<usize>(self.flag)
                .map(|&n| vec![(k, Setting::Count(n))]),
            Kind::Real(k) => m
                .get_one::<f64>(self.flag)
                .map(|&v| vec![(k, Setting::Real(v))]),
            Kind::Grid { x, y } => m
                .get_one::<(usize, usize)>(self.flag)
                .map(|&(gx, gy)| vec![(x, Setting::Count(gx)), (y, Setting::Count(gy))]),
            Kind::Search { stride, keep } => {
                m.get_one::<Search>(self.flag).map(|Search(s)| match s {
                    Some(s) => vec![
                        (stride, Setting::Count(s.stride)),
                        (keep, Setting::Count(s.keep)),
                    ],
                    None => vec![(stride, Setting::Off)],
                })
            }
        }
        .unwrap_or_default()
    }
}

/// The knob flags given, as knob settings (the last layer).
#[derive(Debug, Clone, Default)]
pub struct Knobs(Vec<(Knob, Setting)>);

impl FromArgMatches for Knobs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut knobs = Knobs::default();
        knobs.update_from_arg_matches(m)?;
        Ok(knobs)
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        for flag in KNOBS {
            let settings = flag.settings(m);
            if !settings.is_empty() {
                let knobs = flag.kind.knobs();
                self.0.retain(|(k, _)| !knobs.contains(k));
                self.0.extend(settings);
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
    pub fn resolve(&self) -> anyhow::Result<ValidConfig> {
        self.resolve_on(self.preset.unwrap_or_default())
    }

    /// Each of `presets` with these flags laid over it as a comparison does
    /// ([`touchc_eval::trade::configs`]: the `--preset` asked takes every `--set`, the
    /// others those their tables have), and a sentence for each `--set` left out.
    #[allow(clippy::type_complexity)]
    pub fn resolve_presets(
        &self,
        presets: &[Preset],
    ) -> anyhow::Result<(Vec<(Preset, ValidConfig)>, Vec<String>)> {
        let layers = self.layers(self.preset.unwrap_or_default())?;
        let (configs, off) = touchc_eval::trade::configs(&layers, presets, self.preset)
            .map_err(super::report::config_usage)?;
        self.check_sampling()?;
        let skipped = off
            .iter()
            .map(|(preset, t)| {
                format!(
                    "--set {} is not applied to --preset {}: `{}` is off there",
                    super::report::clip(&t.assignment),
                    preset.name(),
                    t.table
                )
            })
            .collect();
        Ok((configs, skipped))
    }

    /// The config these flags describe, laid over `preset` whatever `--preset` says.
    /// Every error is a usage error (exit status 2): the parameters are how the command
    /// was called, the `--config` file included. So are `--rate` and `--pitch-mm`
    /// outside the ranges any recording may have.
    pub fn resolve_on(&self, preset: Preset) -> anyhow::Result<ValidConfig> {
        self.build(&self.layers(preset)?)
    }

    /// `layers` built, its error in the flags' words, and the sampling flags checked.
    fn build(&self, layers: &Layers) -> anyhow::Result<ValidConfig> {
        let config = layers.build().map_err(super::report::config_usage)?;
        self.check_sampling()?;
        Ok(config)
    }

    /// `--rate` and `--pitch-mm` against the ranges a recording's own values must meet.
    fn check_sampling(&self) -> anyhow::Result<()> {
        use touchc_model::config::{PITCH_MM_RANGE, RATE_HZ_RANGE};
        for (flag, value, range, unit) in [
            ("--rate", self.rate, RATE_HZ_RANGE, "Hz"),
            ("--pitch-mm", self.pitch_mm, PITCH_MM_RANGE, "mm"),
        ] {
            if let Some(v) = value.filter(|v| !range.contains(v)) {
                return Err(super::report::usage(format!(
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

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{Args, Command};

    /// The config `args` (flags of [`ConfigArgs`]) describe.
    fn resolved(args: &[&str]) -> Config {
        let cmd = ConfigArgs::augment_args(Command::new("t"));
        let m = cmd
            .try_get_matches_from(std::iter::once("t").chain(args.iter().copied()))
            .unwrap();
        ConfigArgs::from_arg_matches(&m)
            .unwrap()
            .resolve()
            .unwrap()
            .into_config()
    }

    /// The value of `knob` in `config`'s TOML image, found by the knob's section and key.
    fn value_of(config: &Config, knob: Knob) -> Option<toml::Value> {
        lookup(&toml::Table::try_from(config).unwrap(), knob).cloned()
    }

    /// A flag of one knob is its key with dashes (`--blur-sigma-mm` sets
    /// `preprocess.blur_sigma_mm`), so a knob renamed in the table renames its flag or
    /// fails here; a flag of two knobs is named by what they share.
    #[test]
    fn a_knob_flag_is_named_by_its_key() {
        for flag in KNOBS {
            let want = match flag.kind {
                Kind::Count(k) | Kind::Real(k) => k.key().replace('_', "-"),
                Kind::Grid { x, y } => {
                    let (x, y) = (x.key(), y.key());
                    assert_eq!(
                        x.strip_suffix("_x"),
                        y.strip_suffix("_y"),
                        "--{}",
                        flag.flag
                    );
                    x.trim_end_matches("_x").replace('_', "-")
                }
                Kind::Search { stride, keep } => {
                    let table = |k: Knob| k.key().split_once('.').map(|(t, _)| t.to_string());
                    assert_eq!(table(stride), table(keep), "--{}", flag.flag);
                    table(stride).unwrap_or_default().replace('_', "-")
                }
            };
            assert_eq!(flag.flag, want);
        }
    }

    /// Every knob flag writes the knobs it names, and only through their section and
    /// key, to a config that round-trips through TOML: a flag or a field renamed on one
    /// side only fails here.
    #[test]
    fn every_knob_flag_sets_its_knobs_through_toml() {
        let base = Config::default();
        for flag in KNOBS {
            let long = format!("--{}", flag.flag);
            // A value other than the default, within range.
            let (value, want): (String, Vec<(Knob, toml::Value)>) = match flag.kind {
                Kind::Count(k) => {
                    let d = value_of(&base, k).and_then(|v| v.as_integer()).unwrap();
                    let n = if d > 1 { d - 1 } else { d + 1 };
                    (n.to_string(), vec![(k, toml::Value::Integer(n))])
                }
                Kind::Real(k) => {
                    let d = value_of(&base, k).and_then(|v| v.as_float()).unwrap();
                    let v = 0.75 * d;
                    (v.to_string(), vec![(k, toml::Value::Float(v))])
                }
                Kind::Grid { x, y } => (
                    "7,9".into(),
                    vec![(x, toml::Value::Integer(7)), (y, toml::Value::Integer(9))],
                ),
                Kind::Search { stride, keep } => (
                    "3,16".into(),
                    vec![
                        (stride, toml::Value::Integer(3)),
                        (keep, toml::Value::Integer(16)),
                    ],
                ),
            };
            let config = resolved(&[&long, &value]);
            for (knob, v) in want {
                assert_eq!(value_of(&config, knob), Some(v), "{long} {value}: {knob}");
            }
            let text = toml::to_string(&config).unwrap();
            assert_eq!(toml::from_str::<Config>(&text).unwrap(), config, "{long}");
            // Everything else keeps the preset's value.
            let changed = Knob::ALL
                .iter()
                .filter(|&&k| value_of(&config, k) != value_of(&base, k))
                .count();
            let expected = match flag.kind {
                Kind::Count(_) | Kind::Real(_) => 1,
                Kind::Grid { .. } | Kind::Search { .. } => 2,
            };
            assert_eq!(changed, expected, "{long} {value}");
        }
        // `off` removes the search's table.
        let fast = ConfigArgs::augment_args(Command::new("t"))
            .try_get_matches_from(["t", "--preset", "fast", "--coarse-to-fine", "off"])
            .unwrap();
        let fast = ConfigArgs::from_arg_matches(&fast)
            .unwrap()
            .resolve()
            .unwrap();
        assert_eq!(fast.placement.coarse_to_fine, None);
    }

    /// A key of a table the preset leaves out (`paper` has no contact regions) names
    /// the table as off and what would turn it on, beside serde's missing field.
    #[test]
    fn a_key_of_a_table_the_preset_leaves_out_says_the_table_is_off() {
        let args = ConfigArgs::augment_args(Command::new("t"))
            .try_get_matches_from([
                "t",
                "--preset",
                "paper",
                "--set",
                "track.regions.seed_psi=0.1",
            ])
            .unwrap();
        let err = ConfigArgs::from_arg_matches(&args)
            .unwrap()
            .resolve()
            .unwrap_err();
        let text = super::super::report::message(&err);
        assert!(text.contains("missing field `footprint_psi`"), "{text}");
        assert!(
            text.contains("`track.regions` is off under --preset paper")
                && text.contains("footprint_psi, join_cells")
                && text.contains("--preset touch"),
            "{text}"
        );
        // A table the preset has takes a single key.
        let args = ConfigArgs::augment_args(Command::new("t"))
            .try_get_matches_from(["t", "--set", "track.regions.seed_psi=0.1"])
            .unwrap();
        let touch = ConfigArgs::from_arg_matches(&args)
            .unwrap()
            .resolve()
            .unwrap();
        assert_eq!(touch.track.regions.map(|r| r.seed_psi), Some(0.1));
    }
}
