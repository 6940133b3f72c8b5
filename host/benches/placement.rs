//! The whole 4,200-transform search on the reference trajectories (the published Python
//! needs 6.4 s for stroke_60 and 12.8 s for tap_pat_200 on this machine kind).

use criterion::{criterion_group, criterion_main, Criterion};
use serde::Deserialize;
use std::hint::black_box;
use touchc::config::Config;
use touchc::layout::Layout;
use touchc::placement::place;
use touchc::trajectory::Trajectory;

#[derive(Deserialize)]
struct RefTrajectory {
    times: Vec<usize>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    costs: Vec<f64>,
}

#[derive(Deserialize)]
struct Reference {
    tared_shape: [usize; 3],
    trajectories: Vec<RefTrajectory>,
}

fn load(name: &str) -> (Vec<Trajectory>, usize, usize) {
    let path = format!(
        "{}/tests/data/{name}.reference.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).expect("reference JSON");
    let r: Reference = serde_json::from_str(&text).expect("reference JSON");
    let trajs = r
        .trajectories
        .into_iter()
        .map(|t| Trajectory {
            values: vec![0.0; t.times.len()],
            frames: t.times,
            rows: t.rows,
            cols: t.cols,
            costs: t.costs,
        })
        .collect();
    (trajs, r.tared_shape[1], r.tared_shape[2])
}

fn bench(c: &mut Criterion) {
    let cfg = Config::default();
    let k = cfg.preprocess.upsample;
    let pitch = cfg.input.cell_mm / k as f64;
    let layout = Layout::paper();
    for name in ["tap_pat_200", "stroke_60"] {
        let (trajs, rows, cols) = load(name);
        c.bench_function(&format!("place/{name}"), |b| {
            b.iter(|| {
                place(
                    black_box(&trajs),
                    rows * k,
                    cols * k,
                    pitch,
                    &layout,
                    &cfg.placement,
                )
                .expect("valid reference input")
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
