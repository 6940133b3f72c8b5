//! Perception studies of stimuli: the scenario classification experiment of the paper
//! (participants feel each stimulus and give a probability per scenario, then rate it
//! on the Self-Assessment Manikin) and its analyses.
//!
//! - [`Responses`] / [`Trial`]: one response set, whatever it was collected with;
//!   [`tidy`] reads and writes its tidy per-trial CSV, [`log`] the JSON-lines session
//!   log that a study run appends to.
//! - [`analyse`] computes a [`Report`]: the top-choice confusion matrix, accuracy with
//!   a Wilson interval, recall and precision, binomial tests against chance, the first
//!   round against all, accuracy against a probability cut-off, Bhattacharyya
//!   coefficients against a reference matrix, k-means over the probability vectors,
//!   and Kruskal-Wallis with Dunn-Sidak post-hoc tests on valence and arousal.
//! - [`figures`] draws the report as SVG, [`markdown`] writes it as tables.
//! - [`order`]: the seeded presentation orders, so that a resumed session replays the
//!   orders it began with.
//!
//! Every statistic is checked against scipy and scikit-learn (`scripts/study-oracle.sh`).

#![deny(missing_docs)]

mod classify;
mod cluster;
mod data;
pub mod figures;

pub mod log;
pub mod markdown;

pub mod order;
mod rank;
mod report;
pub mod special;
pub mod tidy;

pub use classify::{bhattacharyya, top_choice, wilson_interval};
pub use cluster::{kmeans, KMeansRun};
pub use data::{DataError, Reference, Responses, Trial};
pub use rank::{dunn_sidak, kruskal_wallis, KruskalWallis};
pub use report::{
    analyse, Accuracy, ClusterCandidate, Clustering, Cutoffs, Rating, Report, RoundReport, Settings,
};
