//! The whole analysis of a response set, as one serialisable value.

use serde::Serialize;

use crate::classify::{
    accuracy_at_cutoff, bhattacharyya, confusion, recall_precision, row_normalised, top_choice,
    top_tied, wilson_interval,
};
use crate::cluster::{calinski_harabasz, kmeans, silhouette};
use crate::rank::{dunn_sidak, kruskal_wallis, KruskalWallis};
use crate::special::binomial_test;
use crate::{Reference, Responses};

/// The analysis's own choices.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Seeds the k-means++ starts.
    pub seed: u64,
    /// k-means starts per number of clusters.
    pub starts: usize,
    /// The most clusters tried (from 2).
    pub max_k: usize,
    /// The probability cut-offs of the non-forced-choice simulation.
    pub cutoffs: Vec<f64>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            seed: 0,
            starts: 10,
            max_k: 10,
            cutoffs: (0..=20).map(|i| i as f64 / 20.0).collect(),
        }
    }
}

/// Top-choice accuracy with its 95 % Wilson interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Accuracy {
    /// Correct over all.
    pub value: f64,
    /// Trials whose top choice was the stimulus's scenario.
    pub correct: u64,
    /// Trials.
    pub trials: u64,
    /// The interval's lower end.
    pub ci95_low: f64,
    /// The interval's upper end.
    pub ci95_high: f64,
}

/// The first classification round alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RoundReport {
    /// Its number.
    pub round: u32,
    /// Its accuracy.
    pub accuracy: Accuracy,
    /// Its confusion counts.
    pub confusion: Vec<Vec<u64>>,
}

/// Accuracy when a right top choice counts only if the `n` largest probabilities sum
/// to at least the cut-off (the supplement's non-forced-choice simulation).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cutoffs {
    /// The cut-offs.
    pub cutoff: Vec<f64>,
    /// Accuracy per cut-off, the top probability alone.
    pub top1: Vec<f64>,
    /// The two largest summed.
    pub top2: Vec<f64>,
    /// The three largest summed.
    pub top3: Vec<f64>,
}

/// k-means with one number of clusters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClusterCandidate {
    /// Clusters.
    pub k: usize,
    /// Calinski-Harabasz index (higher is better).
    pub calinski_harabasz: f64,
    /// Mean silhouette (higher is better).
    pub silhouette: f64,
    /// Sum of squared distances to the centers.
    pub inertia: f64,
    /// The k-means++ start of the kept run.
    pub init: Vec<Vec<f64>>,
    /// The cluster means.
    pub centers: Vec<Vec<f64>>,
}

/// k-means over the probability vectors of the classification trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Clustering {
    /// Every number of clusters tried.
    pub candidates: Vec<ClusterCandidate>,
    /// The `k` of the highest Calinski-Harabasz index.
    pub k_calinski_harabasz: usize,
    /// The `k` of the highest mean silhouette.
    pub k_silhouette: usize,
    /// The `k` reported below: the Calinski-Harabasz choice (the paper's).
    pub k: usize,
    /// Each classification trial's cluster, in the order of the trials.
    pub labels: Vec<usize>,
    /// Per cluster, the trials of each stimulus scenario in it.
    pub membership: Vec<Vec<u64>>,
}

/// One Self-Assessment Manikin scale per stimulus scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rating {
    /// Ratings per stimulus scenario.
    pub count: Vec<usize>,
    /// Median per stimulus scenario.
    pub median: Vec<Option<f64>>,
    /// Across the stimulus scenarios.
    pub kruskal_wallis: Option<KruskalWallis>,
    /// Dunn-Sidak p-values between stimulus scenarios.
    pub dunn_sidak: Vec<Vec<Option<f64>>>,
}

/// The Kruskal-Wallis tests of both scales.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KruskalBoth {
    /// Valence.
    pub valence: Option<KruskalWallis>,
    /// Arousal.
    pub arousal: Option<KruskalWallis>,
}

/// Everything the report says.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The scenarios, the order of every row and column below.
    pub scenarios: Vec<String>,
    /// Distinct participants.
    pub participants: usize,
    /// Classification trials.
    pub trials: usize,
    /// Classification trials whose largest probability was shared.
    pub top_ties: usize,
    /// 1 / scenarios.
    pub chance: f64,
    /// Top-choice accuracy; `None` without classification trials.
    pub accuracy: Option<Accuracy>,
    /// Rows: the stimulus's scenario; columns: the top choice.
    pub confusion: Vec<Vec<u64>>,
    /// `confusion` with each row summing to 1 (`None` for an empty row).
    pub confusion_normalised: Vec<Option<Vec<f64>>>,
    /// Per scenario.
    pub recall: Vec<Option<f64>>,
    /// Per scenario.
    pub precision: Vec<Option<f64>>,
    /// Per stimulus scenario: the two-sided exact binomial test of its correct top
    /// choices against chance.
    pub binomial_p: Vec<Option<f64>>,
    /// The first classification round.
    pub first_round: Option<RoundReport>,
    /// The non-forced-choice simulation.
    pub cutoffs: Option<Cutoffs>,
    /// Per stimulus row, against the reference's row.
    pub bhattacharyya: Option<Vec<Option<f64>>>,
    /// Clusters of the probability vectors.
    pub clustering: Option<Clustering>,
    /// Valence.
    pub valence: Rating,
    /// Arousal.
    pub arousal: Rating,
    /// Both scales' Kruskal-Wallis tests.
    pub kruskal_wallis: KruskalBoth,
}

fn accuracy(trials: &[(usize, &[f64])]) -> Option<Accuracy> {
    let n = trials.len() as u64;
    let k = trials.iter().filter(|(s, p)| top_choice(p) == *s).count() as u64;
    let (lo, hi) = wilson_interval(k, n)?;
    Some(Accuracy {
        value: k as f64 / n as f64,
        correct: k,
        trials: n,
        ci95_low: lo,
        ci95_high: hi,
    })
}

fn median(v: &[f64]) -> Option<f64> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(s[n / 2]),
        _ => Some((s[n / 2 - 1] + s[n / 2]) / 2.0),
    }
}

fn rating(groups: Vec<Vec<f64>>) -> Rating {
    Rating {
        count: groups.iter().map(Vec::len).collect(),
        median: groups.iter().map(|g| median(g)).collect(),
        kruskal_wallis: kruskal_wallis(&groups),
        dunn_sidak: dunn_sidak(&groups),
    }
}

fn clustering(
    points: &[Vec<f64>],
    stimuli: &[usize],
    n: usize,
    s: &Settings,
) -> Option<Clustering> {
    let mut distinct = points.to_vec();
    distinct.sort_by(|a, b| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    distinct.dedup();
    let top = s
        .max_k
        .min(distinct.len())
        .min(points.len().saturating_sub(1));
    let mut candidates = Vec::new();
    let mut runs = Vec::new();
    for k in 2..=top {
        let Some(run) = kmeans(points, k, s.seed, s.starts) else {
            continue;
        };
        candidates.push(ClusterCandidate {
            k,
            calinski_harabasz: calinski_harabasz(points, &run.labels, k),
            silhouette: silhouette(points, &run.labels, k),
            inertia: run.inertia,
            init: run.init.clone(),
            centers: run.centers.clone(),
        });
        runs.push(run);
    }
    let best = |f: fn(&ClusterCandidate) -> f64| {
        (0..candidates.len()).fold(0, |b, i| {
            if f(&candidates[i]) > f(&candidates[b]) {
                i
            } else {
                b
            }
        })
    };
    if candidates.is_empty() {
        return None;
    }
    let (ich, isil) = (best(|c| c.calinski_harabasz), best(|c| c.silhouette));
    let run = &runs[ich];
    let mut membership = vec![vec![0u64; n]; run.k];
    for (&l, &st) in run.labels.iter().zip(stimuli) {
        membership[l][st] += 1;
    }
    Some(Clustering {
        k_calinski_harabasz: candidates[ich].k,
        k_silhouette: candidates[isil].k,
        k: run.k,
        labels: run.labels.clone(),
        membership,
        candidates,
    })
}

/// The analysis of `responses`, with Bhattacharyya coefficients when a `reference` is
/// given (its scenarios are matched by name).
pub fn analyse(responses: &Responses, reference: Option<&Reference>, s: &Settings) -> Report {
    let n = responses.scenarios.len();
    let trials: Vec<(usize, &[f64])> = responses
        .classified()
        .map(|(t, p)| (t.stimulus, p))
        .collect();
    let m = confusion(n, trials.iter().copied());
    let (recall, precision) = recall_precision(&m);
    let chance = 1.0 / n as f64;
    let binomial_p = (0..n)
        .map(|i| binomial_test(m[i][i], m[i].iter().sum(), chance))
        .collect();
    let first = responses.classified().map(|(t, _)| t.round).min();
    let first_round = first.and_then(|r| {
        let ft: Vec<(usize, &[f64])> = responses
            .classified()
            .filter(|(t, _)| t.round == r)
            .map(|(t, p)| (t.stimulus, p))
            .collect();
        Some(RoundReport {
            round: r,
            accuracy: accuracy(&ft)?,
            confusion: confusion(n, ft.iter().copied()),
        })
    });
    let cutoffs = (!trials.is_empty()).then(|| {
        let at = |top| {
            s.cutoffs
                .iter()
                .map(|c| accuracy_at_cutoff(&trials, top, *c))
                .collect()
        };
        Cutoffs {
            cutoff: s.cutoffs.clone(),
            top1: at(1),
            top2: at(2),
            top3: at(3),
        }
    });
    let bhattacharyya = reference.map(|r| {
        responses
            .scenarios
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let row = r.scenarios.iter().position(|x| x == name)?;
                let cols: Option<Vec<f64>> = responses
                    .scenarios
                    .iter()
                    .map(|c| {
                        r.scenarios
                            .iter()
                            .position(|x| x == c)
                            .map(|j| r.rows[row][j])
                    })
                    .collect();
                let observed: Vec<f64> = m[i].iter().map(|c| *c as f64).collect();
                bhattacharyya(&observed, &cols?)
            })
            .collect()
    });
    let points: Vec<Vec<f64>> = trials.iter().map(|(_, p)| p.to_vec()).collect();
    let stimuli: Vec<usize> = trials.iter().map(|(st, _)| *st).collect();
    let valence = rating(responses.ratings(|t| t.valence));
    let arousal = rating(responses.ratings(|t| t.arousal));
    let mut people: Vec<&str> = responses
        .trials
        .iter()
        .map(|t| t.participant.as_str())
        .collect();
    people.sort_unstable();
    people.dedup();
    Report {
        scenarios: responses.scenarios.clone(),
        participants: people.len(),
        trials: trials.len(),
        top_ties: trials.iter().filter(|(_, p)| top_tied(p)).count(),
        chance,
        accuracy: accuracy(&trials),
        confusion_normalised: row_normalised(&m),
        confusion: m,
        recall,
        precision,
        binomial_p,
        first_round,
        cutoffs,
        bhattacharyya,
        clustering: clustering(&points, &stimuli, n, s),
        kruskal_wallis: KruskalBoth {
            valence: valence.kruskal_wallis,
            arousal: arousal.kruskal_wallis,
        },
        valence,
        arousal,
    }
}
