//! Labelled synthetic data sets: the synthesiser's gestures mixed per class, with
//! per-person variation (speed, pressure, place along the arm), for tests, examples
//! and the benchmark, so selection runs without a lab's recordings.
//!
//! A class is a mix of gesture sequences (its "scenario"); each recording draws one
//! sequence, and each person has their own speed, pressure and place along the arm.

use ndarray::{s, Array3};
use touchc_synth::{generate, Gesture, Sensor, SynthSpec, Tuning};

use crate::rng::Rng;

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct SetSpec {
    /// Number of classes, 2 to 6 (the paper's scenarios, in [`CLASSES`] order).
    pub classes: usize,
    /// Recordings per class.
    pub per_class: usize,
    /// Number of people; recording `i` of a class is by person `i % people`.
    pub people: usize,
    /// The sensor imitated.
    pub sensor: Sensor,
    /// Every recording exactly this many frames (quiet frames before, as the paper
    /// padded in front), or as long as its gestures.
    pub frames: Option<usize>,
    /// The seed: the same spec gives the same recordings.
    pub seed: u64,
}

/// The classes' names and gesture mixes: each recording draws one of its class's
/// sequences.
pub const CLASSES: [(&str, &[&[Gesture]]); 6] = [
    (
        "attention",
        &[&[Gesture::Tap], &[Gesture::Tap, Gesture::Tap]],
    ),
    (
        "calming",
        &[&[Gesture::Stroke, Gesture::Stroke], &[Gesture::Strokes]],
    ),
    (
        "gratitude",
        &[&[Gesture::Squeeze], &[Gesture::Squeeze, Gesture::Pat]],
    ),
    (
        "happiness",
        &[&[Gesture::Shake], &[Gesture::Pat, Gesture::Shake]],
    ),
    (
        "love",
        &[&[Gesture::Hand], &[Gesture::Palm, Gesture::Stroke]],
    ),
    (
        "sadness",
        &[&[Gesture::Rub], &[Gesture::Palm, Gesture::Rub]],
    ),
];

/// One labelled recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Labelled {
    /// Its class's name.
    pub class: String,
    /// Its person, `p0`, `p1`, ...
    pub group: String,
    /// Frames `[T, rows, cols]`, psi, NaN where the sleeve has no cell.
    pub frames: Array3<f64>,
}

/// A person's way of touching: how fast, how hard, and where along the arm.
struct Person {
    speed: f64,
    pressure: f64,
    shift: isize,
}

fn person(seed: u64, p: usize) -> Person {
    let mut rng = Rng::new(seed ^ (0x5eed_0000 + p as u64));
    Person {
        speed: 0.7 + 0.6 * rng.uniform(),
        pressure: 0.6 + 0.8 * rng.uniform(),
        shift: rng.below(5) as isize - 2,
    }
}

/// The recordings of `spec`, class by class.
pub fn labelled_set(spec: &SetSpec) -> Vec<Labelled> {
    let mut out = Vec::new();
    let mut rng = Rng::new(spec.seed);
    for (class, mixes) in CLASSES.iter().take(spec.classes.clamp(2, 6)) {
        for i in 0..spec.per_class {
            let p = i % spec.people.max(1);
            let who = person(spec.seed, p);
            let gestures = mixes[rng.below(mixes.len())].to_vec();
            let tuning = Tuning {
                stroke_speed_mps: Some(0.25 * who.speed),
                tap_s: Some(0.2 / who.speed),
                shake_hz: Some(3.0 * who.speed),
                ..Tuning::default()
            };
            let synth = SynthSpec {
                gestures,
                seed: rng.next_u64(),
                sensor: spec.sensor,
                tuning,
                quiet_frames: 10,
                ..SynthSpec::default()
            };
            let raw = generate(&synth).mapv(|v| v * who.pressure);
            let frames = shifted(&raw, who.shift);
            let frames = match spec.frames {
                Some(n) => fitted(&frames, n, synth.noise_psi, &mut rng),
                None => frames,
            };
            out.push(Labelled {
                class: class.to_string(),
                group: format!("p{p}"),
                frames,
            });
        }
    }
    out
}

/// The touch moved `shift` columns along the arm, keeping the sleeve's outline (NaN
/// cells stay NaN; cells uncovered by the move read 0).
fn shifted(x: &Array3<f64>, shift: isize) -> Array3<f64> {
    let (_, _, cols) = x.dim();
    let mut out = x.mapv(|v| if v.is_nan() { v } else { 0.0 });
    for c in 0..cols {
        let from = c as isize - shift;
        if from < 0 || from >= cols as isize {
            continue;
        }
        let src = x.slice(s![.., .., from as usize]).to_owned();
        let mut dst = out.slice_mut(s![.., .., c]);
        ndarray::Zip::from(&mut dst).and(&src).for_each(|d, &v| {
            if !d.is_nan() && !v.is_nan() {
                *d = v;
            }
        });
    }
    out
}

/// `x` cut or padded in front with sensor noise to exactly `n` frames.
fn fitted(x: &Array3<f64>, n: usize, noise: f64, rng: &mut Rng) -> Array3<f64> {
    let (t, rows, cols) = x.dim();
    if t >= n {
        return x.slice(s![..n, .., ..]).to_owned();
    }
    let mut out = Array3::zeros((n, rows, cols));
    for i in 0..n - t {
        for r in 0..rows {
            for c in 0..cols {
                out[[i, r, c]] = if x[[0, r, c]].is_nan() {
                    f64::NAN
                } else {
                    noise * rng.normal()
                };
            }
        }
    }
    out.slice_mut(s![n - t.., .., ..]).assign(x);
    out
}

/// The recordings of `spec` as a data set in memory (classes in [`CLASSES`] order,
/// grouped by person), at the sensor's rate and pitch.
pub fn dataset(spec: &SetSpec) -> crate::Dataset {
    use crate::dataset::{Item, Listing, Sample};
    let set = labelled_set(spec);
    let classes: Vec<String> = CLASSES
        .iter()
        .take(spec.classes.clamp(2, 6))
        .map(|(c, _)| c.to_string())
        .collect();
    let items = set
        .iter()
        .enumerate()
        .map(|(i, l)| Item {
            path: format!("{}/{i}.npy", l.class).into(),
            label: classes.iter().position(|c| *c == l.class).unwrap_or(0),
            group: Some(l.group.clone()),
        })
        .collect();
    let samples = set
        .into_iter()
        .map(|l| Sample {
            frames: l.frames.mapv(|v| if v.is_nan() { 0.0 } else { v as f32 }),
            rate_hz: spec.sensor.rate_hz(),
            pitch_mm: spec.sensor.pitch_mm(),
        })
        .collect();
    crate::Dataset {
        listing: Listing {
            source: "synthetic".into(),
            classes,
            items,
        },
        samples,
    }
}

/// Writes `set` as a data set: `dir/<class>/<class>_<i>.npy` and `dir/manifest.csv`
/// (`path,label,group`, paths relative to `dir`).
pub fn write(dir: &std::path::Path, set: &[Labelled]) -> Result<(), crate::SelectError> {
    let io = |path: &std::path::Path| {
        let path = path.to_path_buf();
        move |source| crate::SelectError::Io { path, source }
    };
    let mut manifest = String::from("path,label,group\n");
    for (i, l) in set.iter().enumerate() {
        let sub = dir.join(&l.class);
        std::fs::create_dir_all(&sub).map_err(io(&sub))?;
        let rel = format!("{}/{}_{i:04}.npy", l.class, l.class);
        let bytes = touchc_synth::to_npy(&l.frames)
            .map_err(|e| crate::SelectError::Setting(format!("cannot encode {rel}: {e}")))?;
        let path = dir.join(&rel);
        std::fs::write(&path, bytes).map_err(io(&path))?;
        manifest.push_str(&format!("{rel},{},{}\n", l.class, l.group));
    }
    let path = dir.join("manifest.csv");
    std::fs::write(&path, manifest).map_err(io(&path))
}
