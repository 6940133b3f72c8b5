//! A trained scorer: what it was trained on (classes, sensor shape) and its weights, as
//! a JSON file that [`Model::from_json`] reads back to score new recordings.

use std::path::Path;
use std::sync::atomic::Ordering;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dataset::Sample;
use crate::logistic::Logistic;
use crate::select::{Control, Progress};
use crate::{features, SelectError};

/// Which scorer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScorerKind {
    /// Multinomial logistic regression on [`features`].
    Features,
    /// The paper's 3D convolutional network ([`cnn`](crate::cnn)).
    Cnn,
}

impl ScorerKind {
    /// The scorer's name in reports and model files.
    pub fn name(self) -> &'static str {
        match self {
            ScorerKind::Features => "features",
            ScorerKind::Cnn => "cnn",
        }
    }
}

/// How a scorer is trained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// The scorer.
    pub kind: ScorerKind,
    /// Seed of shuffles and initial weights.
    pub seed: u64,
    /// Passes over the training set (the network; the features scorer fits to
    /// convergence).
    pub epochs: usize,
}

/// What the model file's first field says, so another JSON file is told apart.
const FORMAT: &str = "touchc-select-model";
/// The version of the file's layout: 2 holds the network scorer's ensemble (`nets`),
/// 1 one network (`net`), which this version still reads.
const VERSION: u32 = 2;

/// A network model's `nets` (a list, version 2) or `net` (one network, version 1).
fn one_or_many<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<crate::cnn::Net>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        Many(Vec<crate::cnn::Net>),
        One(Box<crate::cnn::Net>),
    }
    Ok(match OneOrMany::deserialize(d)? {
        OneOrMany::Many(nets) => nets,
        OneOrMany::One(net) => vec![*net],
    })
}

/// The weights of one scorer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
enum Weights {
    Features {
        names: Vec<String>,
        logistic: Logistic,
    },
    Cnn {
        /// The ensemble ([`crate::cnn::train_ensemble`]); a version 1 file's single
        /// `net` reads as an ensemble of one.
        #[serde(alias = "net", deserialize_with = "one_or_many")]
        nets: Vec<crate::cnn::Net>,
    },
}

/// A trained scorer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Model {
    format: String,
    version: u32,
    /// The classes, in score order.
    pub classes: Vec<String>,
    /// Rows and columns of the sensor it was trained on.
    pub shape: [usize; 2],
    weights: Weights,
}

impl Model {
    /// Trains on `samples` with classes `labels` (indices into `classes`). `fold` is
    /// the fold reported in progress (`None`: the model of the whole data set).
    pub fn train(
        samples: &[&Sample],
        labels: &[usize],
        classes: &[String],
        settings: &Settings,
        fold: Option<usize>,
        control: &Control,
    ) -> Result<Self, SelectError> {
        let shape = samples.first().map_or([0, 0], |s| {
            let (_, r, c) = s.frames.dim();
            [r, c]
        });
        let weights = match settings.kind {
            ScorerKind::Features => {
                let x = feature_rows(samples, control)?;
                let logistic = Logistic::fit(&x, labels, classes.len());
                (control.progress)(Progress {
                    fold,
                    network: 1,
                    networks: 1,
                    epoch: 1,
                    epochs: 1,
                    loss: f64::NAN,
                });
                Weights::Features {
                    names: features::NAMES.iter().map(|s| s.to_string()).collect(),
                    logistic,
                }
            }
            ScorerKind::Cnn => Weights::Cnn {
                nets: crate::cnn::train_ensemble(
                    samples,
                    labels,
                    classes.len(),
                    settings,
                    fold,
                    control,
                )?,
            },
        };
        Ok(Model {
            format: FORMAT.into(),
            version: VERSION,
            classes: classes.to_vec(),
            shape,
            weights,
        })
    }

    /// The scorer this model is.
    pub fn kind(&self) -> ScorerKind {
        match self.weights {
            Weights::Features { .. } => ScorerKind::Features,
            Weights::Cnn { .. } => ScorerKind::Cnn,
        }
    }

    /// Each sample's score for each class (probabilities summing to 1).
    pub fn score(
        &self,
        samples: &[&Sample],
        control: &Control,
    ) -> Result<Vec<Vec<f64>>, SelectError> {
        match &self.weights {
            Weights::Features { logistic, .. } => Ok(feature_rows(samples, control)?
                .iter()
                .map(|row| logistic.predict(row))
                .collect()),
            Weights::Cnn { nets } => {
                let scores: Vec<Option<Vec<f64>>> = samples
                    .par_iter()
                    .map(|s| {
                        (!control.cancel.load(Ordering::Relaxed))
                            .then(|| crate::cnn::predict_ensemble(nets, s))
                    })
                    .collect();
                scores
                    .into_iter()
                    .map(|r| r.ok_or(SelectError::Cancelled))
                    .collect()
            }
        }
    }

    /// The model as the JSON of a model file.
    pub fn to_json(&self) -> Vec<u8> {
        // A tree of numbers and strings: serialising it cannot fail.
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// Reads a model file's bytes; `path` names it in errors.
    pub fn from_json(path: &Path, bytes: &[u8]) -> Result<Self, SelectError> {
        let bad = |problem: String| SelectError::ModelFile {
            path: path.to_path_buf(),
            problem,
        };
        let value: serde_json::Value = serde_json::from_slice(bytes)
            .map_err(|e| bad(format!("not a model file (not JSON: {e})")))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(bad(format!(
                "not a model file (no \"format\": \"{FORMAT}\")"
            )));
        }
        let model: Model = serde_json::from_value(value)
            .map_err(|e| bad(format!("a model file this version cannot read ({e})")))?;
        if !(1..=VERSION).contains(&model.version) {
            return Err(bad(format!(
                "model file version {}, this version reads 1 to {VERSION}",
                model.version
            )));
        }
        let consistent = match &model.weights {
            Weights::Features { names, logistic } => {
                names.len() == features::COUNT
                    && logistic.mean.len() == names.len()
                    && logistic.scale.len() == names.len()
                    && logistic.classes == model.classes.len()
                    && logistic.weights.len() == logistic.classes * (names.len() + 1)
            }
            Weights::Cnn { nets } => {
                !nets.is_empty()
                    && nets.iter().all(|net| {
                        net.consistent(model.classes.len()) && net.shape() == model.shape
                    })
            }
        };
        if !consistent || model.classes.len() < 2 {
            return Err(bad("its weights do not fit its classes and features".into()));
        }
        Ok(model)
    }

    /// Checks that `sample` (named `name`) has the sensor shape the model was trained on.
    pub fn check_shape(&self, name: &str, sample: &Sample) -> Result<(), SelectError> {
        let (_, r, c) = sample.frames.dim();
        if [r, c] != self.shape {
            return Err(SelectError::MixedShapes {
                first: "the model".into(),
                rows1: self.shape[0],
                cols1: self.shape[1],
                second: name.into(),
                rows2: r,
                cols2: c,
            });
        }
        Ok(())
    }
}

/// The features of every sample, in parallel, stopping early when cancelled.
fn feature_rows(samples: &[&Sample], control: &Control) -> Result<Vec<Vec<f64>>, SelectError> {
    let rows: Vec<Option<Vec<f64>>> = samples
        .par_iter()
        .map(|s| (!control.cancel.load(Ordering::Relaxed)).then(|| features::extract(s)))
        .collect();
    rows.into_iter()
        .map(|r| r.ok_or(SelectError::Cancelled))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;

    /// A version 1 model file (one network under `net`) still reads, as an ensemble of
    /// that one network, and scores as it does.
    #[test]
    fn a_version_1_network_file_reads_as_one_network() {
        let mut rng = crate::rng::Rng::new(3);
        let samples: Vec<Sample> = (0..4)
            .map(|_| Sample {
                frames: ndarray::Array3::from_shape_fn((40, 8, 8), |_| rng.uniform() as f32),
                rate_hz: 20.0,
                pitch_mm: 25.4,
            })
            .collect();
        let refs: Vec<&Sample> = samples.iter().collect();
        let classes = vec!["a".to_string(), "b".to_string()];
        let cancel = AtomicBool::new(false);
        let control = Control {
            cancel: &cancel,
            progress: &|_| {},
        };
        let settings = Settings {
            kind: ScorerKind::Cnn,
            seed: 1,
            epochs: 1,
        };
        let model = Model::train(&refs, &[0, 1, 0, 1], &classes, &settings, None, &control);
        let Ok(model) = model else {
            panic!("training failed: {model:?}")
        };
        let path = Path::new("m.json");
        let mut v1: serde_json::Value =
            serde_json::from_slice(&model.to_json()).unwrap_or_default();
        assert_eq!(v1["version"], 2);
        let first = v1["weights"]["nets"][0].take();
        v1["weights"] = serde_json::json!({ "kind": "cnn", "net": first });
        v1["version"] = 1.into();
        let bytes = serde_json::to_vec(&v1).unwrap_or_default();
        let read = Model::from_json(path, &bytes);
        let Ok(read) = read else {
            panic!("version 1 refused: {read:?}")
        };
        let Weights::Cnn { nets } = &read.weights else {
            panic!("not a network model")
        };
        assert_eq!(nets.len(), 1);
        let scores = read.score(&refs, &control).unwrap_or_default();
        let want: Vec<Vec<f64>> = samples.iter().map(|s| nets[0].predict(s)).collect();
        assert_eq!(scores, want);
        // The file as written reads back whole; a version from the future does not.
        assert_eq!(
            Model::from_json(path, &model.to_json()).ok(),
            Some(model.clone())
        );
        v1["version"] = 3.into();
        let future = serde_json::to_vec(&v1).unwrap_or_default();
        assert!(Model::from_json(path, &future).is_err());
    }
}
