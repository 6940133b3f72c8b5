//! CPU time per stage of `touchc track` on one recording (default: the bench's
//! synthetic 705-frame recording). `cargo run --release --example stage_times [REC.npy]`

use touchc_testkit as common;

/// Nanoseconds this thread has spent on a CPU (Linux schedstat): on a machine shared with
/// other builds, wall time mostly measures the neighbours.
fn cpu_ns() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| {
            s.split_whitespace()
                .next()
                .and_then(|v| v.parse::<f64>().ok())
        })
        .unwrap_or(f64::NAN)
}

#[derive(Clone, Copy)]
struct Instant(f64);

impl Instant {
    fn now() -> Self {
        Instant(cpu_ns())
    }
}

impl std::ops::Sub for Instant {
    type Output = std::time::Duration;
    fn sub(self, rhs: Self) -> std::time::Duration {
        std::time::Duration::from_nanos((self.0 - rhs.0).max(0.0) as u64)
    }
}

use ndarray_npy::WriteNpyExt;
use touchc_input::recording::Recording;
use touchc_pipeline::track::track;
use touchc_tracking::detect::detect;
use touchc_tracking::preprocess::preprocess;
use touchc_tracking::track::link;

fn main() -> anyhow::Result<()> {
    let cfg = touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper);
    let dir = tempfile::tempdir()?;
    let path = match std::env::args().nth(1) {
        Some(p) => p.into(),
        None => {
            let p = dir.path().join("synthetic.npy");
            common::moving_blobs(705, 4, 42).write_npy(std::fs::File::create(&p)?)?;
            p
        }
    };
    let reps = 20;
    let paper = touchc_model::config::Sampling::PAPER;
    let mut t_track = 0.0;
    let (mut t_load, mut t_tare, mut t_blur, mut t_detect, mut t_flow) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut summary = String::new();
    for _ in 0..reps {
        let t0 = Instant::now();
        let rec = Recording::load(&path)?;
        let t1 = Instant::now();
        let tared = rec.tare(&cfg.input, &paper)?;
        let t2 = Instant::now();
        let blurred = preprocess(tared.view(), &cfg.preprocess, &paper)?;
        let t3 = Instant::now();
        let dets = detect(&blurred, &cfg.detect);
        let t4 = Instant::now();
        let trajs = link(&dets, &cfg.track, &paper)?.trajectories;
        let t5 = Instant::now();
        let t6 = Instant::now();
        let rec2 = Recording::load(&path)?;
        let out = track(&rec2, &cfg)?;
        t_track += (Instant::now() - t6).as_secs_f64();
        assert_eq!(out.trajectories, trajs);
        t_load += (t1 - t0).as_secs_f64();
        t_tare += (t2 - t1).as_secs_f64();
        t_blur += (t3 - t2).as_secs_f64();
        t_detect += (t4 - t3).as_secs_f64();
        t_flow += (t5 - t4).as_secs_f64();
        summary = format!(
            "{}: {:?} -> {} detections, {} trajectories",
            path.display(),
            rec.dim(),
            dets.all.len(),
            trajs.len()
        );
    }
    let ms = |t: f64| t * 1e3 / reps as f64;
    println!("{summary}");
    println!(
        "CPU ms per run (mean of {reps}): load {:.2}  tare {:.2}  blur {:.2}  detect {:.2}  flow {:.2}  total {:.2}",
        ms(t_load),
        ms(t_tare),
        ms(t_blur),
        ms(t_detect),
        ms(t_flow),
        ms(t_load + t_tare + t_blur + t_detect + t_flow)
    );
    println!(
        "CPU ms per run, load + track() (maxima fused into the blur loop): {:.2}",
        ms(t_track)
    );
    Ok(())
}
