//! The scorers learn what the synthesiser makes separable, and their scores depend on
//! the seed alone.

use std::sync::atomic::AtomicBool;

use touchc_select::model::Settings;
use touchc_select::synthetic::{dataset, SetSpec};
use touchc_select::{cross_validate, Control, Folds, ScorerKind};
use touchc_synth::Sensor;

fn spec(per_class: usize) -> SetSpec {
    SetSpec {
        classes: 6,
        per_class,
        people: 6,
        sensor: Sensor::Sleeve,
        frames: None,
        seed: 7,
    }
}

fn run(kind: ScorerKind, per_class: usize, grouped: bool) -> touchc_select::Selection {
    let data = dataset(&spec(per_class));
    let groups = data.groups().filter(|_| grouped);
    let folds = Folds::new(&data.labels(), groups.as_deref(), 3, 1).unwrap();
    let cancel = AtomicBool::new(false);
    let control = Control {
        cancel: &cancel,
        progress: &|_| {},
    };
    cross_validate(
        &data,
        &Settings {
            kind,
            seed: 1,
            epochs: 30,
        },
        &folds,
        &control,
    )
    .unwrap()
}

#[test]
fn features_learn_six_separable_classes_far_above_chance() {
    let s = run(ScorerKind::Features, 24, true);
    assert!(s.folds.grouped);
    // Chance is 1/6.
    assert!(s.metrics.accuracy > 0.7, "accuracy {}", s.metrics.accuracy);
    assert!(s.metrics.macro_f1 > 0.65, "macro-F1 {}", s.metrics.macro_f1);
}

#[test]
fn features_scores_are_reproducible() {
    let a = run(ScorerKind::Features, 8, false);
    let b = run(ScorerKind::Features, 8, false);
    assert_eq!(a.scores, b.scores);
}
