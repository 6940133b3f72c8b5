//! k-fold cross-validation splits: stratified (each class dealt evenly over the folds)
//! or, when recordings carry groups, grouped (each group in exactly one fold, so a
//! person's touches are never both trained on and scored).

use std::collections::BTreeMap;

use crate::rng::Rng;
use crate::SelectError;

/// Which fold holds out each recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Folds {
    /// `fold[i]`: the fold in which recording `i` is scored.
    pub fold: Vec<usize>,
    /// Number of folds.
    pub k: usize,
    /// True when groups were kept whole.
    pub grouped: bool,
}

impl Folds {
    /// Splits recordings with classes `labels` (and `groups`, when given) into `k`
    /// folds, shuffled by `seed`.
    pub fn new(
        labels: &[usize],
        groups: Option<&[String]>,
        k: usize,
        seed: u64,
    ) -> Result<Self, SelectError> {
        if k < 2 {
            return Err(SelectError::Setting(format!(
                "{k} fold(s): cross-validation needs at least 2"
            )));
        }
        if labels.len() < k {
            return Err(SelectError::Folds(format!(
                "{} recordings cannot be split into {k} folds",
                labels.len()
            )));
        }
        let mut rng = Rng::new(seed);
        let fold = match groups {
            Some(groups) => grouped(groups, k, &mut rng)?,
            None => stratified(labels, k, &mut rng),
        };
        Ok(Folds {
            fold,
            k,
            grouped: groups.is_some(),
        })
    }

    /// The recordings scored in fold `f`.
    pub fn test(&self, f: usize) -> Vec<usize> {
        (0..self.fold.len())
            .filter(|&i| self.fold[i] == f)
            .collect()
    }

    /// The recordings trained on in fold `f`.
    pub fn train(&self, f: usize) -> Vec<usize> {
        (0..self.fold.len())
            .filter(|&i| self.fold[i] != f)
            .collect()
    }
}

/// Each class's recordings shuffled and dealt round the folds, continuing where the
/// previous class stopped so the folds' sizes differ by one at most.
fn stratified(labels: &[usize], k: usize, rng: &mut Rng) -> Vec<usize> {
    let mut by_class: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, &l) in labels.iter().enumerate() {
        by_class.entry(l).or_default().push(i);
    }
    let mut fold = vec![0; labels.len()];
    let mut next = 0;
    for members in by_class.values_mut() {
        rng.shuffle(members);
        for &i in members.iter() {
            fold[i] = next % k;
            next += 1;
        }
    }
    fold
}

/// Groups shuffled, then placed largest first, each into the fold that holds fewest
/// recordings so far (as scikit-learn's `GroupKFold` balances them).
fn grouped(groups: &[String], k: usize, rng: &mut Rng) -> Result<Vec<usize>, SelectError> {
    let mut members: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, g) in groups.iter().enumerate() {
        members.entry(g.as_str()).or_default().push(i);
    }
    if members.len() < k {
        return Err(SelectError::Folds(format!(
            "{} group(s) cannot be split into {k} folds that keep each group whole",
            members.len()
        )));
    }
    let mut order: Vec<Vec<usize>> = members.into_values().collect();
    rng.shuffle(&mut order);
    // Stable: equal sizes keep their shuffled order.
    order.sort_by_key(|m| std::cmp::Reverse(m.len()));
    let mut sizes = vec![0usize; k];
    let mut fold = vec![0; groups.len()];
    for m in order {
        let f = (0..k).min_by_key(|&f| (sizes[f], f)).unwrap_or(0);
        sizes[f] += m.len();
        for i in m {
            fold[i] = f;
        }
    }
    Ok(fold)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grouped_folds_never_split_a_group_and_use_every_fold() {
        let groups: Vec<String> = (0..97).map(|i| format!("p{}", (i * 7) % 11)).collect();
        let labels: Vec<usize> = (0..97).map(|i| i % 3).collect();
        let folds = Folds::new(&labels, Some(&groups), 5, 3).unwrap();
        let mut fold_of: BTreeMap<&str, usize> = BTreeMap::new();
        for (g, &f) in groups.iter().zip(&folds.fold) {
            assert_eq!(*fold_of.entry(g).or_insert(f), f, "group {g} split");
        }
        for f in 0..5 {
            assert!(!folds.test(f).is_empty());
        }
    }

    #[test]
    fn stratified_folds_balance_every_class() {
        let labels: Vec<usize> = (0..50).map(|i| i % 2).collect();
        let folds = Folds::new(&labels, None, 5, 9).unwrap();
        for f in 0..5 {
            let test = folds.test(f);
            assert_eq!(test.len(), 10);
            assert_eq!(test.iter().filter(|&&i| labels[i] == 0).count(), 5);
        }
    }

    #[test]
    fn too_few_groups_is_an_error() {
        let groups: Vec<String> = (0..10).map(|i| format!("p{}", i % 3)).collect();
        let labels = vec![0; 10];
        assert!(Folds::new(&labels, Some(&groups), 5, 1).is_err());
    }
}
