//! Labelled synthetic data sets: the synthesiser's gestures mixed per class, with
//! per-person variation, for tests, examples and the benchmark, so selection runs
//! without a lab's recordings.
//!
//! Two kinds ([`Mix`]). `Separable`: each class its own gestures, people differing a
//! little; a scorer that learns anything gets (nearly) all of it right, so a test can
//! ask that it does. `Realistic`: what a lab's recordings look like: classes share
//! gestures in different proportions (a tap says "attention" more often than
//! "happiness", but both), every person has their own speed, pressure, place on the
//! arm, hold and pause lengths and favourite gestures, every recording varies around its
//! person's way and starts after its own quiet spell, and the sensor's noise and flicker
//! differ from one recording to the next. Some recordings of one class then look like
//! another's and no scorer reaches 1. `Gestures`: the classes are touch gestures
//! themselves, seven of them including no touch ([`GESTURES`]), made the realistic
//! way: a proxy for a lab's gesture data set of ten people on a 10 x 10 fabric grid.

use ndarray::{s, Array3};
use touchc_synth::{generate, Gesture, Sensor, SynthSpec, Tuning};

use crate::rng::Rng;

/// How far apart the classes are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mix {
    /// Each class its own gestures ([`CLASSES`]); people vary a little.
    Separable,
    /// Classes share gestures in different proportions ([`REALISTIC`]); people and
    /// recordings vary widely, the sensor is noisy and flickers.
    Realistic,
    /// Seven classes that are touch gestures, including no touch ([`GESTURES`]), each
    /// mostly its own gesture and at times one a person would mistake for it; people,
    /// recordings and the sensor vary as in `Realistic`.
    Gestures,
}

impl Mix {
    /// The classes' names, in label order.
    pub fn classes(self) -> Vec<&'static str> {
        match self {
            Mix::Gestures => GESTURES.iter().map(|(name, _)| *name).collect(),
            Mix::Separable | Mix::Realistic => CLASSES.iter().map(|(name, _)| *name).collect(),
        }
    }
}

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct SetSpec {
    /// Number of classes, from 2 to all of the mix's ([`Mix::classes`], in order).
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
    /// How far apart the classes are.
    pub mix: Mix,
    /// The seed: the same spec gives the same recordings.
    pub seed: u64,
}

/// The classes' names and gesture mixes of [`Mix::Separable`]: each recording draws
/// one of its class's sequences.
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

/// The gesture mixes of [`Mix::Realistic`], in [`CLASSES`] order: each gesture of a
/// recording is drawn with these weights (percent), reweighted by the person's taste.
/// Each class has a gesture it is mostly made of, and every gesture serves two or more
/// classes, as people touch to say different things with the same hands: a reader who
/// knew each recording's gestures exactly would still name the class right only about
/// 80 % of the time (their most likely class; a simulation of these weights).
pub const REALISTIC: [&[(Gesture, u32)]; 6] = [
    // attention
    &[
        (Gesture::Tap, 60),
        (Gesture::Pat, 20),
        (Gesture::Squeeze, 10),
        (Gesture::Shake, 10),
    ],
    // calming
    &[
        (Gesture::Strokes, 60),
        (Gesture::Stroke, 20),
        (Gesture::Rub, 10),
        (Gesture::Hand, 10),
    ],
    // gratitude
    &[
        (Gesture::Squeeze, 60),
        (Gesture::Hand, 20),
        (Gesture::Pat, 10),
        (Gesture::Tap, 10),
    ],
    // happiness
    &[
        (Gesture::Shake, 60),
        (Gesture::Tickle, 20),
        (Gesture::Pat, 10),
        (Gesture::Tap, 10),
    ],
    // love
    &[
        (Gesture::Stroke, 55),
        (Gesture::Palm, 20),
        (Gesture::Hand, 15),
        (Gesture::Strokes, 10),
    ],
    // sadness
    &[
        (Gesture::Rub, 55),
        (Gesture::Palm, 25),
        (Gesture::Hand, 10),
        (Gesture::Squeeze, 10),
    ],
];

/// The classes and gesture mixes of [`Mix::Gestures`] (percent, reweighted by the
/// person's taste): the seven gestures of a touch-gesture data set, no touch among
/// them. Each class is mostly its own gesture; the rest is what a person asked for one
/// gesture sometimes does instead (a quick pat is a tap, a slow rub a stroke, a
/// tickle's fingertips scratch), so the classes overlap as a real set's do.
pub const GESTURES: [(&str, &[(Gesture, u32)]); 7] = [
    ("none", &[(Gesture::Rest, 100)]),
    (
        "constant",
        &[
            (Gesture::Palm, 45),
            (Gesture::Hand, 35),
            (Gesture::Squeeze, 20),
        ],
    ),
    ("pat", &[(Gesture::Pat, 60), (Gesture::Tap, 40)]),
    (
        "rub",
        &[
            (Gesture::Rub, 60),
            (Gesture::Strokes, 25),
            (Gesture::Stroke, 15),
        ],
    ),
    ("scratch", &[(Gesture::Scratch, 60), (Gesture::Tickle, 40)]),
    (
        "stroke",
        &[
            (Gesture::Stroke, 55),
            (Gesture::Strokes, 25),
            (Gesture::Rub, 20),
        ],
    ),
    (
        "tickle",
        &[
            (Gesture::Tickle, 60),
            (Gesture::Scratch, 20),
            (Gesture::Tap, 20),
        ],
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

/// A person's way of touching: how fast, how hard, where along the arm, how long they
/// hold and pause, and (realistic sets) how much they like each gesture.
struct Person {
    speed: f64,
    pressure: f64,
    shift: isize,
    hold: f64,
    gap: f64,
    /// Multiplies each gesture's weight, by [`Gesture`] index in [`POOL`].
    taste: [f64; POOL.len()],
}

/// Every gesture a realistic class may use, for the people's tastes.
const POOL: [Gesture; 10] = [
    Gesture::Tap,
    Gesture::Tickle,
    Gesture::Pat,
    Gesture::Shake,
    Gesture::Squeeze,
    Gesture::Stroke,
    Gesture::Strokes,
    Gesture::Rub,
    Gesture::Hand,
    Gesture::Palm,
];

fn person(spec: &SetSpec, p: usize) -> Person {
    let mut rng = Rng::new(spec.seed ^ (0x5eed_0000 + p as u64));
    if spec.mix == Mix::Separable {
        return Person {
            speed: 0.7 + 0.6 * rng.uniform(),
            pressure: 0.6 + 0.8 * rng.uniform(),
            shift: rng.below(5) as isize - 2,
            hold: 1.0,
            gap: 1.0,
            taste: [1.0; POOL.len()],
        };
    }
    let mut taste = [1.0; POOL.len()];
    // Log-normal tastes: some people pat half as often as the mix says, others twice.
    taste
        .iter_mut()
        .for_each(|t| *t = (0.5 * rng.normal()).exp());
    Person {
        // Half to twice the typical speed, a third to nearly twice the pressure.
        speed: (0.35 * rng.normal()).exp().clamp(0.5, 2.0),
        pressure: (0.4 * rng.normal()).exp().clamp(0.35, 1.9),
        shift: rng.below(7) as isize - 3,
        hold: 0.5 + rng.uniform(),
        gap: 0.5 + 2.0 * rng.uniform(),
        taste,
    }
}

/// One recording's gestures: one to three drawn from the class's mix weighted by the
/// person's taste (1 for a gesture outside [`POOL`]).
fn realistic_gestures(mix: &[(Gesture, u32)], who: &Person, rng: &mut Rng) -> Vec<Gesture> {
    let weights: Vec<(Gesture, f64)> = mix
        .iter()
        .map(|&(g, w)| {
            let taste = POOL
                .iter()
                .position(|&p| p == g)
                .map_or(1.0, |k| who.taste[k]);
            (g, f64::from(w) * taste)
        })
        .collect();
    let total: f64 = weights.iter().map(|w| w.1).sum();
    let count = 1 + usize::from(rng.uniform() < 0.45) + usize::from(rng.uniform() < 0.15);
    (0..count)
        .map(|_| {
            let mut u = rng.uniform() * total;
            for &(g, w) in &weights {
                if u < w {
                    return g;
                }
                u -= w;
            }
            weights[weights.len() - 1].0
        })
        .collect()
}

/// A recording's synthesis: the person's way, varied for this recording.
fn recording(spec: &SetSpec, class: usize, who: &Person, rng: &mut Rng) -> (SynthSpec, f64, isize) {
    if spec.mix == Mix::Separable {
        let mixes = CLASSES[class].1;
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
        return (synth, who.pressure, who.shift);
    }
    let mix = match spec.mix {
        Mix::Gestures => GESTURES[class].1,
        Mix::Separable | Mix::Realistic => REALISTIC[class],
    };
    let gestures = realistic_gestures(mix, who, rng);
    // This recording around the person's way: +-15 % speed, +-20 % pressure, now and
    // then a cell further along the arm.
    let speed = who.speed * (0.15 * rng.normal()).exp();
    let pressure = who.pressure * (0.2 * rng.normal()).exp();
    let shift = who.shift + [-1, 0, 0, 0, 1][rng.below(5)];
    let tuning = Tuning {
        stroke_speed_mps: Some(0.3 * speed),
        tap_s: Some(0.2 / speed),
        shake_hz: Some(3.0 * speed),
        shake_amplitude_mm: Some(spec.sensor.pitch_mm() * (1.2 + 1.3 * rng.uniform())),
        gap_s: Some(0.15 * who.gap),
        gap_max_s: Some(0.4 * who.gap),
        strokes: Some(2 + rng.below(3)),
        hold_s: Some(3.0 * who.hold * (0.2 * rng.normal()).exp()),
    };
    let synth = SynthSpec {
        gestures,
        seed: rng.next_u64(),
        sensor: spec.sensor,
        tuning,
        quiet_frames: 5 + rng.below(40),
        noise_psi: 0.003 + 0.009 * rng.uniform(),
        flicker: 3.0 * rng.uniform(),
        ..SynthSpec::default()
    };
    (synth, pressure, shift)
}

/// The recordings of `spec`, class by class.
pub fn labelled_set(spec: &SetSpec) -> Vec<Labelled> {
    let mut out = Vec::new();
    let mut rng = Rng::new(spec.seed);
    let people: Vec<Person> = (0..spec.people.max(1)).map(|p| person(spec, p)).collect();
    let names = spec.mix.classes();
    let count = spec.classes.clamp(2, names.len());
    for (class, name) in names.into_iter().enumerate().take(count) {
        for i in 0..spec.per_class {
            let p = i % people.len();
            let (synth, pressure, shift) = recording(spec, class, &people[p], &mut rng);
            let raw = generate(&synth).mapv(|v| v * pressure);
            let frames = shifted(&raw, shift);
            let frames = match spec.frames {
                Some(n) => fitted(&frames, n, synth.noise_psi, &mut rng),
                None => frames,
            };
            out.push(Labelled {
                class: name.to_string(),
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
    let names = spec.mix.classes();
    let classes: Vec<String> = names
        .iter()
        .take(spec.classes.clamp(2, names.len()))
        .map(|c| c.to_string())
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
