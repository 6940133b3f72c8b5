//! touchc: recorded touch -> trajectories -> actuator placement -> stimulus file.
//!
//! The pipeline lives in one crate per layer under `host/crates/` (see
//! `docs/architecture.md`); this package is the `touchc` command line and its pictures
//! ([`viz`]), and names the layers' crates under the modules its tests, benchmarks and
//! fuzz targets use:
//!
//! | stage | module (crate) | hands on |
//! |---|---|---|
//! | - | [`config`], [`crop`], [`display`], [`geometry`], [`layout`], [`stage`], [`trajectory`] (`touchc-model`) | the model every stage shares |
//! | 0 load, tare | [`input`] (`touchc-input`) | tared frames |
//! | 1-3 crop, blur, detections, trajectories | [`tracking`] (`touchc-tracking`) | [`trajectory::Trajectory`] |
//! | 4 placement | [`placement`] (`touchc-placement`) | circles, chosen trajectories |
//! | 5-6 actuator signals, conditioning | [`rendering`] (`touchc-rendering`) | 8 currents at 1 kHz |
//! | 7 keyframes | [`encoding`] (`touchc-encoding`) | the stimulus file |
//!
//! [`compile`] runs them in order on the active scene and [`track`] runs stages 0-3
//! (`touchc-pipeline`, with [`coverage`] and [`rendered`]); [`measure`] (`touchc-eval`) measures compiles
//! against synthetic truth and the presets against each other.

#![warn(missing_docs)]

pub use touchc_model::{config, crop, display, geometry, layout, stage, trajectory};

pub use touchc_encoding as encoding;
pub use touchc_input as input;
pub use touchc_placement as placement;
pub use touchc_rendering as rendering;
pub use touchc_select as select;
pub use touchc_tracking as tracking;

pub use touchc_export as export;

pub use touchc_eval as measure;
pub use touchc_pipeline::{compile, coverage, rendered, track};

#[cfg(feature = "viz")]
pub mod viz;

#[cfg(feature = "link")]
pub use touchc_link as link;
