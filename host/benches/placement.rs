//! The whole 4,200-transform search on the reference trajectories (the published Python
//! needs 6.4 s for stroke_60 and 12.8 s for tap_pat_200 on this machine kind).

use touchc_testkit as common;

use common::Reference;
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use touchc_model::layout::Layout;
use touchc_placement::place;

fn bench(c: &mut Criterion) {
    let cfg = touchc_model::config::Config::preset(touchc_model::config::Preset::Paper);
    let k = cfg.preprocess.upsample;
    let pitch = cfg.input.pitch_mm / k as f64;
    let layout = Layout::paper();
    for name in ["tap_pat_200", "stroke_60"] {
        let r = Reference::load(name);
        let (trajs, rows, cols) = (r.trajectories(), r.tared_shape[1], r.tared_shape[2]);
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
