//! Tracking and rendering measured on the synthetic cases of real touch
//! ([`touchc_synth::cases`]) under each preset: one row per case, sensor, rate,
//! seed and preset (`touchc trade --cases`, `docs/trade.md`).

use serde::Serialize;

use touchc_input::recording::{Recording, RecordingError};
use touchc_model::config::{MetadataOverrides, Preset, ValidConfig};
use touchc_pipeline::compile::{compile, CompileError, CompileOptions};
use touchc_synth::cases::{Bar, Case};
use touchc_synth::{self as synth, SynthSpec};

use crate::evaluate::evaluate_compiled;

/// What one preset made of one case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaseRow {
    /// The case's name.
    pub case: String,
    /// The sensor's name.
    pub sensor: &'static str,
    /// The rate the case was sampled at, Hz.
    pub rate_hz: f64,
    /// The seed of the draw.
    pub seed: u64,
    /// The preset.
    pub preset: Preset,
    /// True contacts that press above the touch threshold.
    pub contacts: usize,
    /// Trajectories tracked.
    pub trajectories: usize,
    /// Share of true contacts recalled.
    pub recall: f64,
    /// Trajectories that follow two or more true contacts.
    pub merges: usize,
    /// Handovers of a contact between trajectories.
    pub splits: usize,
    /// Trajectories where nothing presses most of the time.
    pub false_contacts: usize,
    /// Share of the touch pressure within two cells of a tracked contact.
    pub coverage: f64,
    /// Share of the touch pressure a driven actuator plays (see [`touchc_pipeline::rendered`]).
    pub rendered: f64,
    /// The stimulus's length, seconds.
    pub duration_s: f64,
    /// Bytes per second of the stimulus.
    pub bytes_per_s: f64,
    /// Wall seconds of the compile.
    pub seconds: f64,
    /// The bar the case is held to.
    #[serde(skip)]
    pub bar: Bar,
}

impl CaseRow {
    /// The case's bar ([`Bar`]). Smooth cases: recall >= 0.95, coverage >= 0.9, splits
    /// at most a tenth of the true contacts, no merges, no false contacts. Real-like
    /// cases: recall >= 0.95, coverage >= 0.9, at most 1.5 trajectories per true
    /// contact and at most the case's bytes per second.
    pub fn passes(&self) -> bool {
        let tracked = self.recall >= 0.95 && self.coverage >= 0.9;
        match self.bar {
            Bar::Tracking => {
                tracked
                    && 10 * self.splits <= self.contacts
                    && self.merges == 0
                    && self.false_contacts == 0
            }
            Bar::RealLike { max_bytes_per_s } => {
                tracked
                    && 2 * self.trajectories <= 3 * self.contacts
                    && self.bytes_per_s <= max_bytes_per_s
            }
        }
    }
}

/// Why a case could not be measured.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CaseError {
    /// The synthetic recording was refused (it never should be).
    #[error("case {case}: {source}")]
    Recording {
        /// The case.
        case: String,
        /// Why.
        #[source]
        source: RecordingError,
    },
    /// The compile failed.
    #[error("case {case}: {source}")]
    Compile {
        /// The case.
        case: String,
        /// Why.
        #[source]
        source: Box<CompileError>,
    },
}

/// Compiles `case` with seed `seed` under each of `configs` and measures each against the
/// truth; `base` supplies everything but the config and the sampling.
pub fn run_case(
    case: &Case,
    seed: u64,
    base: &CompileOptions,
    configs: &[(Preset, ValidConfig)],
) -> Result<Vec<CaseRow>, CaseError> {
    let spec = SynthSpec {
        seed,
        ..case.spec.clone()
    };
    let (data, truth) = synth::generate_with_truth(&spec);
    let name = format!("{} {} {} Hz", case.name, case.sensor.name(), case.rate_hz);
    let rec = Recording::from_array(name, data.view()).map_err(|source| CaseError::Recording {
        case: case.name.clone(),
        source,
    })?;
    configs
        .iter()
        .map(|(preset, config)| {
            let opts = CompileOptions {
                config: config.clone(),
                metadata: MetadataOverrides {
                    rate_hz: Some(truth.rate_hz),
                    pitch_mm: Some(truth.pitch_mm),
                },
                ..base.clone()
            };
            let compiled = compile(&rec, &opts).map_err(|source| CaseError::Compile {
                case: case.name.clone(),
                source: Box::new(source),
            })?;
            let e = evaluate_compiled(&truth, &rec, &compiled).map_err(|source| {
                CaseError::Recording {
                    case: case.name.clone(),
                    source,
                }
            })?;
            let r = &compiled.report;
            Ok(CaseRow {
                case: case.name.clone(),
                sensor: case.sensor.name(),
                rate_hz: case.rate_hz,
                seed,
                preset: *preset,
                contacts: e.contacts.len(),
                trajectories: e.trajectories,
                recall: e.recall(),
                merges: e.merges,
                splits: e.splits,
                false_contacts: e.false_contacts,
                coverage: e.coverage.ratio(),
                rendered: r.rendered_coverage,
                duration_s: r.duration_s,
                bytes_per_s: r.bytes_per_second,
                seconds: r.seconds.total(),
                bar: case.bar,
            })
        })
        .collect()
}
