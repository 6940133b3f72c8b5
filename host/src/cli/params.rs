//! The algorithm parameters on the command line: `--preset`, `--config FILE`, then
//! one flag per knob, each layer overriding the one before.

use std::path::{Path, PathBuf};

use anyhow::Context;
use touchc::config::{CoarseToFine, Config, MetadataOverrides, Preset};

/// Parameter flags shared by `touchc compile`, `track` and `preview`. Every knob is
/// physical (its unit in its name); a flag not given keeps the preset's value.
#[derive(Debug, Clone, clap::Args)]
pub struct ParamArgs {
    /// Parameter preset: `touch` (the default: real touch, fast strokes, brief taps,
    /// flat hands, flicker, touch at the start), `paper` (the published algorithm, bit
    /// for bit), `fast` (x4 upsampling, coarse-to-fine placement search), `exact` (a
    /// 60,060-transform grid).
    #[arg(long, value_enum, default_value = "touch")]
    pub preset: Preset,
    /// TOML file overriding the preset's parameters (missing keys keep the preset's).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Upsampling factor k. Blur and link gate are in mm and mm/s, so they keep their
    /// physical size.
    #[arg(long)]
    pub upsample: Option<usize>,
    /// Gaussian blur sigma, mm.
    #[arg(long)]
    pub blur_sigma_mm: Option<f64>,
    /// Cost of starting a trajectory, -ln P_entr.
    #[arg(long)]
    pub entry_cost: Option<f64>,
    /// Cost of ending a trajectory, -ln P_exit.
    #[arg(long)]
    pub exit_cost: Option<f64>,
    /// Link gate: the fastest a contact may move between frames, mm/s.
    #[arg(long)]
    pub max_speed_mm_s: Option<f64>,
    /// Most trajectories.
    #[arg(long)]
    pub max_trajectories: Option<usize>,
    /// Transform grid `X,Y` (x points, y points; paper 20,20 = 4,200 transforms) or
    /// `N` for `N,N`.
    #[arg(long, value_parser = parse_grid)]
    pub grid: Option<(usize, usize)>,
    /// Coarse-to-fine placement search `STRIDE,KEEP` (fast: 2,32), or `off`.
    #[arg(long, value_parser = parse_coarse_to_fine)]
    pub coarse_to_fine: Option<Search>,
    /// Workspace centre bonus b of D = w (1 + b - b d^2 / r^2).
    #[arg(long)]
    pub centre_bonus: Option<f64>,
    /// Low-pass cut-off, Hz (below half the recording's rate).
    #[arg(long)]
    pub lowpass_hz: Option<f64>,
    /// Any other parameter, as `SECTION.KEY=VALUE` in TOML syntax (for example
    /// `detect.sigma_k=1.5` or `input.baseline="robust"`); may be repeated. Applied
    /// after the config file.
    #[arg(long = "set", value_name = "SECTION.KEY=VALUE")]
    pub set: Vec<String>,
}

/// The recording's sampling, for every command that reads a recording: over the file's
/// own values (`.npz` `rate_hz`, `pitch_mm`), which are over the config's.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct MetadataArgs {
    /// The recording's frame rate, Hz (default: the file's, else `input.rate_hz`).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// The sensor's cell pitch, mm (default: the file's, else `input.pitch_mm`).
    #[arg(long, value_name = "MM")]
    pub pitch_mm: Option<f64>,
}

impl MetadataArgs {
    /// The overrides these flags describe.
    pub fn overrides(&self) -> MetadataOverrides {
        MetadataOverrides {
            rate_hz: self.rate,
            pitch_mm: self.pitch_mm,
        }
    }
}

/// The placement search a `--coarse-to-fine` flag asks for.
#[derive(Debug, Clone, Copy)]
pub struct Search(Option<CoarseToFine>);

impl ParamArgs {
    /// The config these flags describe.
    pub fn resolve(&self) -> anyhow::Result<Config> {
        let mut c = layered(self.preset, self.config.as_deref(), &self.set)?;
        let set = |dst: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *dst = v;
            }
        };
        if let Some(k) = self.upsample {
            c.preprocess.upsample = k;
        }
        set(&mut c.preprocess.blur_sigma_mm, self.blur_sigma_mm);
        set(&mut c.track.entry_cost, self.entry_cost);
        set(&mut c.track.exit_cost, self.exit_cost);
        set(&mut c.track.max_speed_mm_s, self.max_speed_mm_s);
        if let Some(n) = self.max_trajectories {
            c.track.max_trajectories = n;
        }
        if let Some((x, y)) = self.grid {
            c.placement.grid_x = x;
            c.placement.grid_y = y;
        }
        if let Some(Search(ctf)) = self.coarse_to_fine {
            c.placement.coarse_to_fine = ctf;
        }
        set(&mut c.placement.centre_bonus, self.centre_bonus);
        set(&mut c.signal.lowpass_hz, self.lowpass_hz);
        c.validate().map_err(|e| anyhow::anyhow!("config: {e}"))?;
        Ok(c)
    }
}

/// `preset`, with the keys of the TOML file `path` (if any), then the `SECTION.KEY=VALUE`
/// assignments of `sets`, laid over it.
pub fn layered(preset: Preset, path: Option<&Path>, sets: &[String]) -> anyhow::Result<Config> {
    let base = Config::preset(preset);
    if path.is_none() && sets.is_empty() {
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
            .with_context(|| format!("--set {set}: expected SECTION.KEY=VALUE"))?;
        let (section, field) = key
            .trim()
            .split_once('.')
            .with_context(|| format!("--set {set}: expected SECTION.KEY=VALUE"))?;
        let doc = format!("[{section}]\n{field} = {value}\n");
        let over: toml::Table =
            toml::from_str(&doc).with_context(|| format!("--set {set}: not a TOML value"))?;
        merge(&mut table, over);
    }
    let config: Config = table
        .try_into()
        .with_context(|| format!("--set {}: invalid parameter", sets.join(" --set ")))?;
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("config: {e}"))?;
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
