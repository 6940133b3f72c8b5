//! The cross-validation: each fold's scorer trained on the other folds and scoring its
//! own recordings, so every recording's scores come from a scorer that never saw it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crate::dataset::{Dataset, Sample};
use crate::metrics::Metrics;
use crate::model::{Model, Settings};
use crate::{Folds, ScorerKind, SelectError};

/// Where training is, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// The fold being trained (0-based); `None` for the model of the whole data set.
    pub fold: Option<usize>,
    /// The network being trained (1-based) of the ensemble's [`networks`](Self::networks)
    /// (the features scorer: 1 of 1).
    pub network: usize,
    /// Networks trained per model.
    pub networks: usize,
    /// The epoch just finished (1-based).
    pub epoch: usize,
    /// Epochs in all.
    pub epochs: usize,
    /// The epoch's mean training loss (NaN where the scorer has none to report).
    pub loss: f64,
}

/// How the caller watches and stops a long run.
pub struct Control<'a> {
    /// Set (from another thread, a signal handler) to stop at the next batch.
    pub cancel: &'a AtomicBool,
    /// Called after every epoch.
    pub progress: &'a (dyn Fn(Progress) + Sync),
}

impl Control<'_> {
    /// [`SelectError::Cancelled`] once the cancel flag is set.
    pub fn check(&self) -> Result<(), SelectError> {
        if self.cancel.load(Ordering::Relaxed) {
            Err(SelectError::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// The cross-validated scores of a data set.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The scorer.
    pub kind: ScorerKind,
    /// Scores: one row per recording, one column per class.
    pub scores: Vec<Vec<f64>>,
    /// The folds used.
    pub folds: Folds,
    /// Accuracy, macro-F1, confusion.
    pub metrics: Metrics,
    /// Seconds spent training, summed over the folds.
    pub train_s: f64,
    /// Seconds spent scoring the held-out recordings, summed over the folds.
    pub score_s: f64,
}

/// Scores every recording of `data` with the scorer of `settings`, trained on the
/// folds that do not hold it.
pub fn cross_validate(
    data: &Dataset,
    settings: &Settings,
    folds: &Folds,
    control: &Control,
) -> Result<Selection, SelectError> {
    let labels = data.labels();
    let classes = &data.listing.classes;
    let mut scores = vec![Vec::new(); labels.len()];
    let (mut train_s, mut score_s) = (0.0, 0.0);
    for f in 0..folds.k {
        control.check()?;
        let (train, test) = (folds.train(f), folds.test(f));
        let pick = |idx: &[usize]| {
            idx.iter()
                .map(|&i| &data.samples[i])
                .collect::<Vec<&Sample>>()
        };
        let y: Vec<usize> = train.iter().map(|&i| labels[i]).collect();
        let t0 = Instant::now();
        let model = Model::train(&pick(&train), &y, classes, settings, Some(f), control)?;
        train_s += t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let s = model.score(&pick(&test), control)?;
        score_s += t1.elapsed().as_secs_f64();
        for (i, row) in test.into_iter().zip(s) {
            scores[i] = row;
        }
    }
    let metrics = Metrics::new(&scores, &labels, classes.len());
    Ok(Selection {
        kind: settings.kind,
        scores,
        folds: folds.clone(),
        metrics,
        train_s,
        score_s,
    })
}
