//! Instance selection, as the paper chose what to render: every recording of a labelled
//! data set scored for every class by a classifier that never saw it (k-fold
//! cross-validation, each recording scored by the fold that held it out), then the
//! best-scoring recordings of each class.
//!
//! Two scorers ([`ScorerKind`]): `features`, a multinomial logistic regression on
//! features a haptics researcher would recognise (duration, pressure, contact area,
//! speed, location along the arm, rhythm; [`features`]), and `cnn`, the paper's 3D
//! convolutional network ([`cnn`]).
//!
//! Hands on: a [`Dataset`] of recordings `[T, rows, cols]` with a class each (and a
//! group, the person who touched, where known); gives [`Selection`]: every recording's
//! scores, the cross-validated confusion matrix, accuracy and macro-F1, the top N per
//! class, and a [`Model`] trained on everything that scores new recordings.

#![deny(missing_docs)]

pub mod cnn;
pub mod dataset;
pub mod error;
pub mod features;
pub mod folds;
pub mod logistic;
pub mod metrics;
pub mod model;
mod rng;
pub mod select;
pub mod synthetic;

pub use dataset::{Dataset, Item};
pub use error::SelectError;
pub use folds::Folds;
pub use model::{Model, ScorerKind};
pub use select::{cross_validate, Control, Progress, Selection};
