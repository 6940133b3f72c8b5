//! One response set: the scenarios in their order and one row per trial.

/// One trial: a stimulus felt and what the participant answered.
#[derive(Debug, Clone, PartialEq)]
pub struct Trial {
    /// Who answered.
    pub participant: String,
    /// The round, counted from 1 (the acclimation round is not a trial).
    pub round: u32,
    /// The place in the round, counted from 1.
    pub position: u32,
    /// The scenario the stimulus was made from: an index into [`Responses::scenarios`].
    pub stimulus: usize,
    /// The probability given to each scenario, normalised to sum to 1; `None` in a
    /// round that asks for none (the Self-Assessment Manikin round).
    pub probabilities: Option<Vec<f64>>,
    /// Valence on the Self-Assessment Manikin (1 to 9), if asked.
    pub valence: Option<f64>,
    /// Arousal on the Self-Assessment Manikin (1 to 9), if asked.
    pub arousal: Option<f64>,
}

/// A response set: the scenarios, in the order every matrix of the report uses, and
/// the trials.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Responses {
    /// The scenario names.
    pub scenarios: Vec<String>,
    /// The trials, in the order they were read.
    pub trials: Vec<Trial>,
}

/// A reference confusion matrix (rows: the stimulus's scenario; columns: the scenario
/// chosen), e.g. a human-human study's, in any unit: rows are normalised before use.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The scenario names of the rows and columns, in order.
    pub scenarios: Vec<String>,
    /// One row per scenario.
    pub rows: Vec<Vec<f64>>,
}

/// Why a response set, a reference or a log could not be read or merged.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DataError {
    /// A line of a file is wrong.
    #[error("line {line}: {problem}")]
    Line {
        /// 1-based.
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// The file has no header or no rows.
    #[error("{0}")]
    Shape(String),
    /// Two response sets name different scenarios.
    #[error("the scenarios differ: {first:?} against {other:?}")]
    Scenarios {
        /// The first set's.
        first: Vec<String>,
        /// The other's.
        other: Vec<String>,
    },
    /// A JSON line that does not parse.
    #[error("line {line}: {source}")]
    Json {
        /// 1-based.
        line: usize,
        /// The parser's error.
        source: serde_json::Error,
    },
}

impl Responses {
    /// Appends `other`'s trials; both must name the same scenarios in the same order.
    pub fn merge(&mut self, other: Responses) -> Result<(), DataError> {
        if self.scenarios.is_empty() && self.trials.is_empty() {
            *self = other;
            return Ok(());
        }
        if self.scenarios != other.scenarios {
            return Err(DataError::Scenarios {
                first: self.scenarios.clone(),
                other: other.scenarios,
            });
        }
        self.trials.extend(other.trials);
        Ok(())
    }

    /// One rating scale (`f` picks it from a trial) grouped by the stimulus's scenario.
    pub fn ratings(&self, f: impl Fn(&Trial) -> Option<f64>) -> Vec<Vec<f64>> {
        let mut g = vec![Vec::new(); self.scenarios.len()];
        for t in &self.trials {
            if let Some(v) = f(t) {
                g[t.stimulus].push(v);
            }
        }
        g
    }

    /// The trials that carry probabilities (the classification rounds).
    pub fn classified(&self) -> impl Iterator<Item = (&Trial, &[f64])> {
        self.trials
            .iter()
            .filter_map(|t| t.probabilities.as_deref().map(|p| (t, p)))
    }
}

/// Probabilities scaled to sum to 1, or the problem with them.
pub(crate) fn normalise(raw: &[f64]) -> Result<Vec<f64>, String> {
    if let Some(v) = raw.iter().find(|v| !v.is_finite() || **v < 0.0) {
        return Err(format!("probability {v} is not a finite number >= 0"));
    }
    let sum: f64 = raw.iter().sum();
    if sum <= 0.0 {
        return Err("the probabilities are all zero".into());
    }
    Ok(raw.iter().map(|v| v / sum).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalise_scales_and_refuses_zero_or_negative() {
        assert_eq!(normalise(&[1.0, 3.0]).unwrap(), vec![0.25, 0.75]);
        assert!(normalise(&[0.0, 0.0]).is_err());
        assert!(normalise(&[-1.0, 2.0]).is_err());
        assert!(normalise(&[f64::NAN, 2.0]).is_err());
    }

    #[test]
    fn merge_refuses_other_scenarios() {
        let mut a = Responses {
            scenarios: vec!["x".into()],
            trials: vec![],
        };
        a.merge(Responses {
            scenarios: vec!["x".into()],
            trials: vec![],
        })
        .unwrap();
        assert!(a
            .merge(Responses {
                scenarios: vec!["y".into()],
                trials: vec![],
            })
            .is_err());
    }
}
