//! The whole compile and each of its stages on a ~700-frame synthetic combination (the
//! length of the published code's 215.9 s reference input), per preset, on one core and
//! on all cores. `touchc trade` prints the same split for any recording.

use std::hint::black_box;

use touchc_testkit as common;

use criterion::{criterion_group, criterion_main, Criterion};
use touchc_encoding::keyframes::{encode, HeaderFields, KeyframeOptions};
use touchc_input::recording::Recording;
use touchc_model::config::{Preset, ValidConfig};
use touchc_model::layout::Layout;
use touchc_pipeline::compile::{compile, CompileOptions};
use touchc_placement::place;
use touchc_rendering::condition;
use touchc_tracking::{detect, preprocess, track};

/// The 698-frame combination ([`common::combination_698`]).
fn long_recording() -> Recording {
    Recording::from_array("combination_698", common::combination_698().view())
        .expect("valid synthetic data")
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

fn bench(c: &mut Criterion) {
    let rec = long_recording();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pools = [("1 core", pool(1)), ("all cores", pool(cores))];

    // The whole compile, per preset.
    for preset in Preset::ALL {
        let opts = CompileOptions {
            config: ValidConfig::preset(preset),
            ..CompileOptions::default()
        };
        for (cores, pool) in &pools {
            c.bench_function(&format!("compile/{}/{cores}", preset.name()), |b| {
                b.iter(|| pool.install(|| compile(black_box(&rec), &opts).expect("compiles")))
            });
        }
    }

    // Stage by stage, on the inputs the paper preset's compile hands each stage.
    let opts = CompileOptions {
        config: touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper),
        // The detect stage below runs on the blurred movie the compile otherwise drops.
        keep_scene: true,
        ..CompileOptions::default()
    };
    let cfg = &opts.config;
    let paper = touchc_model::config::Sampling::PAPER;
    let compiled = compile(&rec, &opts).expect("compiles");
    let (tracked, placement, signals) = (
        compiled.tracked.as_ref().expect("touch"),
        compiled.placement.as_ref().expect("trajectories"),
        compiled.signals.as_ref().expect("touch"),
    );
    let tared = rec.tare(&cfg.input, &paper).expect("long enough");
    let (_, rows, cols) = tared.dim();
    c.bench_function("stage/tare", |b| {
        b.iter(|| rec.tare(black_box(&cfg.input), &paper).expect("tare"))
    });
    for (cores, pool) in &pools {
        c.bench_function(&format!("stage/preprocess (whole)/{cores}"), |b| {
            b.iter(|| {
                pool.install(|| {
                    preprocess::preprocess(black_box(tared.view()), &cfg.preprocess, &paper)
                        .expect("blur")
                })
            })
        });
    }
    c.bench_function("stage/detect (whole)", |b| {
        b.iter(|| detect::detect(black_box(&tracked.blurred), &cfg.detect))
    });
    c.bench_function("stage/track (crop)", |b| {
        b.iter(|| track::link(black_box(&tracked.detections), &cfg.track, &paper).expect("link"))
    });
    for preset in Preset::ALL {
        let p = ValidConfig::preset(preset);
        // The placement stage sees the preset's own trajectories.
        let own = compile(
            &rec,
            &CompileOptions {
                config: p.clone(),
                ..CompileOptions::default()
            },
        )
        .expect("compiles");
        let trajs = &own.tracked.as_ref().expect("touch").trajectories;
        let kp = p.preprocess.upsample;
        for (cores, pool) in &pools {
            c.bench_function(&format!("stage/placement/{}/{cores}", preset.name()), |b| {
                b.iter(|| {
                    pool.install(|| {
                        place(
                            black_box(trajs),
                            rows * kp,
                            cols * kp,
                            25.4 / kp as f64,
                            &opts.layout,
                            &p.placement,
                        )
                        .expect("place")
                    })
                })
            });
        }
    }
    c.bench_function("stage/signals", |b| {
        b.iter(|| {
            touchc_rendering::signals::recomputed_actuator_signals(
                black_box(tracked),
                placement,
                tared.view(),
                cfg,
                &paper,
            )
            .expect("signals")
        })
    });
    c.bench_function("stage/condition", |b| {
        b.iter(|| {
            condition::condition(black_box(&signals.psi), &cfg.signal, paper.rate_hz)
                .expect("condition")
        })
    });
    let layout = Layout::paper();
    let fields = HeaderFields {
        name: "bench",
        layout_hash: layout.geometry_hash(),
        layout: layout.id(),
        limits: opts.limits,
    };
    c.bench_function("stage/keyframes", |b| {
        b.iter(|| {
            encode(
                black_box(&compiled.signal),
                fields,
                &KeyframeOptions::new(&cfg.keyframes),
            )
            .expect("encode")
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
