//! Stages 0-3 on a 705-frame 8 x 21 recording (the length of the longest public one),
//! per stage and end to end. The published Python takes about 1.0 s for these stages.

use touchc_testkit as common;

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use ndarray_npy::WriteNpyExt;
use touchc_input::recording::Recording;
use touchc_pipeline::track::track;
use touchc_tracking::detect::detect;
use touchc_tracking::preprocess::preprocess;
use touchc_tracking::track::link;

fn stages(c: &mut Criterion) {
    let cfg = touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper);
    let paper = touchc_model::config::Sampling::PAPER;
    let data = common::moving_blobs(705, 4, 42);
    let mut bytes = Vec::new();
    data.write_npy(&mut bytes).expect("in-memory npy");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bench.npy");
    std::fs::write(&path, &bytes).expect("write npy");

    let rec = Recording::load(&path).expect("load");
    let tared = rec.tare(&cfg.input, &paper).expect("tare");
    let blurred = preprocess(tared.view(), &cfg.preprocess, &paper).expect("blur");
    let dets = detect(&blurred, &cfg.detect);
    let trajs = link(&dets, &cfg.track, &paper).expect("link").trajectories;
    eprintln!(
        "bench recording: {} detections, {} trajectories",
        dets.all.len(),
        trajs.len()
    );

    c.bench_function("load", |b| {
        b.iter(|| Recording::load(black_box(&path)).expect("load"))
    });
    c.bench_function("tare", |b| {
        b.iter(|| rec.tare(black_box(&cfg.input), &paper).expect("tare"))
    });
    c.bench_function("blur", |b| {
        b.iter(|| preprocess(black_box(tared.view()), &cfg.preprocess, &paper).expect("blur"))
    });
    c.bench_function("detect", |b| {
        b.iter(|| detect(black_box(&blurred), &cfg.detect))
    });
    c.bench_function("flow", |b| {
        b.iter(|| link(black_box(&dets), &cfg.track, &paper).expect("link"))
    });
    c.bench_function("total (load + track)", |b| {
        b.iter(|| {
            let rec = Recording::load(black_box(&path)).expect("load");
            track(&rec, &cfg).expect("track")
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = stages
}
criterion_main!(benches);
