//! Real touch, measured: every case of issue 12 on both sensors, under each preset,
//! against the truth of where each contact was (`touchc_eval::evaluate`).

use crate::common;
use touchc_eval::evaluate::{evaluate_compiled, Evaluation};
use touchc_input::recording::Recording;
use touchc_model::config::{Config, MetadataOverrides, Preset, ValidConfig};
use touchc_pipeline::compile::{compile, CompileOptions, Compiled, Warning};
use touchc_rendering::signals::Source;
use touchc_synth::{self as synth, Gesture, Sensor, SynthSpec};

/// One synthetic case: a name and its spec on `sensor`.
struct Case {
    name: String,
    spec: SynthSpec,
}

fn cases(sensor: Sensor) -> Vec<Case> {
    common::touch_cases(sensor)
        .into_iter()
        .map(|(name, spec)| Case { name, spec })
        .collect()
}

/// Compiles `case` under `preset` at the sensor's rate and pitch, and measures it.
fn run(case: &Case, preset: Preset, seed: u64) -> (Evaluation, Compiled) {
    let spec = SynthSpec {
        seed,
        ..case.spec.clone()
    };
    let (data, truth) = synth::generate_with_truth(&spec);
    let rec = Recording::from_array(case.name.clone(), data.view()).unwrap();
    let compiled = compile(
        &rec,
        &CompileOptions {
            config: ValidConfig::preset(preset),
            metadata: MetadataOverrides {
                rate_hz: Some(truth.rate_hz),
                pitch_mm: Some(truth.pitch_mm),
            },
            ..CompileOptions::default()
        },
    )
    .unwrap();
    let e = evaluate_compiled(&truth, &rec, &compiled).unwrap();
    (e, compiled)
}

/// Of the frames and actuators a flat hand covers (the actuator's centre well inside
/// the contact, under half its radius from its centre), the share that render.
fn covered_rendered(case: &Case, compiled: &Compiled, offset: usize) -> Option<f64> {
    let (_, truth) = synth::generate_with_truth(&case.spec);
    let placement = compiled.placement.as_ref()?;
    let signals = compiled.signals.as_ref()?;
    let (mut covered, mut rendered) = (0usize, 0usize);
    for c in truth.contacts.iter().filter(|c| c.gesture == Gesture::Palm) {
        for p in c.points.iter().filter(|p| p.pressure_psi > 0.2) {
            let Some(f) = p.frame.checked_sub(offset) else {
                continue;
            };
            for (ch, circle) in placement.circles.iter().enumerate() {
                let d = ((circle.x_mm - p.x_mm).powi(2) + (circle.y_mm - p.y_mm).powi(2)).sqrt();
                if d < 0.5 * p.radius_mm && f < signals.frames() {
                    covered += 1;
                    rendered += usize::from(signals.source[ch][f] != Source::Silent);
                }
            }
        }
    }
    (covered > 0).then(|| rendered as f64 / covered as f64)
}

/// The bar for the default preset: recall >= 0.95, coverage >= 0.9, no merges,
/// no false contacts, on every case, both sensors, two seeds; `paper` printed beside.
#[test]
fn the_default_renders_every_case_on_both_sensors() {
    assert_eq!(Config::default(), Config::preset(Preset::Touch));
    let mut failures = Vec::new();
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for case in cases(sensor) {
            for seed in [1, 2] {
                let (e, c) = run(&case, Preset::Touch, seed);
                let palm = covered_rendered(&case, &c, 0);
                let (paper, _) = run(&case, Preset::Paper, seed);
                eprintln!(
                    "{:7} {:32} seed {seed}  touch: {}{}  | paper: {}",
                    sensor.name(),
                    case.name,
                    e.summary(),
                    palm.map_or(String::new(), |v| format!(", palm rendered {v:.2}")),
                    paper.summary()
                );
                let ok = e.recall() >= 0.95
                    && e.coverage.ratio() >= 0.9
                    && e.merges == 0
                    && e.false_contacts == 0
                    && palm.is_none_or(|v| v >= 0.9);
                if !ok {
                    failures.push(format!(
                        "{} {} seed {seed}: {}",
                        sensor.name(),
                        case.name,
                        e.summary()
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Compiles `case` (seed 1) under the default preset and measures it.
fn run_default(case: &synth::cases::Case) -> (Evaluation, Compiled) {
    run(
        &Case {
            name: case.name.clone(),
            spec: case.spec.clone(),
        },
        Preset::Touch,
        1,
    )
}

/// The same touch at 20 and at 54 Hz, under the default preset: the same stimulus
/// length within one 1 kHz tick (the recordings last equally long: 1.5 s of quiet on
/// each side of 3 s of touch), and coverage within 0.02.
#[test]
fn the_same_touch_gives_the_same_stimulus_at_any_rate() {
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for name in ["hand with heel", "rub 0.45 m/s"] {
            let at = |rate: f64| {
                let case = synth::cases::cases_on(sensor, rate)
                    .into_iter()
                    .find(|c| c.name == name)
                    .expect("the case");
                run_default(&case)
            };
            let ((e20, c20), (e54, c54)) = (at(20.0), at(54.0));
            let (d20, d54) = (c20.report.duration_s, c54.report.duration_s);
            assert!(
                (d20 - d54).abs() <= 0.001 + 1e-9,
                "{} {name}: {d20} s at 20 Hz, {d54} s at 54 Hz",
                sensor.name()
            );
            let (v20, v54) = (e20.coverage.ratio(), e54.coverage.ratio());
            assert!(
                (v20 - v54).abs() <= 0.02,
                "{} {name}: coverage {v20:.3} at 20 Hz, {v54:.3} at 54 Hz",
                sensor.name()
            );
        }
    }
}

/// Presses held 2 s at each of `at` (row, column), with 1.5 s of quiet on each side, on
/// the paper's 8 x 21 frame at 20 Hz.
fn presses(at: &[(f64, f64)]) -> Recording {
    let data = ndarray::Array3::from_shape_fn((110, 8, 21), |(t, r, c)| {
        let on = if (30..70).contains(&t) { 1.0 } else { 0.0 };
        at.iter()
            .map(|&(y, x)| {
                let d2 = (r as f64 - y).powi(2) + (c as f64 - x).powi(2);
                on * (-d2 / 1.5).exp()
            })
            .sum::<f64>()
    });
    Recording::from_array("presses", data.view()).unwrap()
}

/// Rendered coverage: a press under the sleeve is tracked whole and played in part (its
/// footprint's cells outside every workspace are not played); nine presses spread
/// over the frame, further apart than the workspaces reach, are tracked whole, but the
/// sleeve plays two of them at most: a shortfall, with what to try.
#[test]
fn the_report_says_how_much_of_the_touch_the_sleeve_plays() {
    let one = compile(&presses(&[(3.5, 10.0)]), &CompileOptions::default())
        .unwrap()
        .report;
    assert!(one.coverage > 0.95, "{}", one.coverage);
    assert!(
        (0.2..0.95).contains(&one.rendered_coverage),
        "{}",
        one.rendered_coverage
    );
    assert!(one.shortfall.is_none());
    assert!(one.rendered_detail.explained_psi > 0.0);
    let spread: Vec<(f64, f64)> = [0.5, 3.5, 6.5]
        .iter()
        .flat_map(|&r| [1.0, 10.0, 19.0].map(|c| (r, c)))
        .collect();
    let apart = compile(&presses(&spread), &CompileOptions::default())
        .unwrap()
        .report;
    assert!(apart.coverage > 0.95, "{}", apart.coverage);
    let s = apart.shortfall.unwrap_or_else(|| {
        panic!(
            "no shortfall: {} {}",
            apart.coverage, apart.rendered_coverage
        )
    });
    assert_eq!(s.rendered, apart.rendered_coverage);
    assert!(s.rendered < 0.2 * s.tracked, "{s:?}");
    assert!(
        apart
            .warnings
            .iter()
            .any(|w| matches!(w, Warning::Shortfall(x) if *x == s)),
        "{:?}",
        apart.warnings
    );
}

/// The 15 light strokes at 54 Hz, measured by `touchc trade --cases`'s runner: the
/// default keeps one trajectory per stroke; `paper` (no bridging, entry and exit 8)
/// cuts them into pieces, which the splits count.
#[test]
fn fifteen_strokes_stay_fifteen_trajectories_under_the_default() {
    use touchc_eval::cases::run_case;
    let case = synth::cases::cases_on(Sensor::Sleeve, 54.0)
        .into_iter()
        .find(|c| c.name.starts_with("15 strokes"))
        .expect("the case");
    let configs = [Preset::Touch, Preset::Paper].map(|p| (p, ValidConfig::preset(p)));
    let rows = run_case(&case, 1, &CompileOptions::default(), &configs).unwrap();
    let (touch, paper) = (&rows[0], &rows[1]);
    assert_eq!(touch.contacts, 15);
    assert!(touch.passes(), "{touch:?}");
    assert!((12..=18).contains(&touch.trajectories), "{touch:?}");
    assert!(paper.splits >= 5 && !paper.passes(), "{paper:?}");
}

/// A broad contact's rim is tracked, but it does not pull the placement off where the
/// hand presses: lattice points below a contact's top weigh less than its top, so on
/// the shipped emoji recordings (flat hands, squeezes) the sleeve plays about as much
/// of the touch as with splitting on the top only (0.38 on `sadness.npy`), where rim
/// points weighted like the top played 0.21.
#[test]
fn a_broad_contacts_rim_does_not_pull_the_placement_off_its_pressure() {
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let rec = Recording::load(manifest.join("../examples/emoji/sadness.npy")).unwrap();
    // The lattice (the default before regions, whose footprints need no lattice).
    let mut lattice = Config::default();
    lattice.track.regions = None;
    lattice.detect.split = Some(touchc_model::config::Split::LATTICE);
    let default = compile(
        &rec,
        &CompileOptions {
            config: lattice.clone().validated().unwrap(),
            ..CompileOptions::default()
        },
    )
    .unwrap()
    .report;
    let mut top_only = lattice;
    if let Some(split) = top_only.detect.split.as_mut() {
        split.extent = None;
    }
    let top = compile(
        &rec,
        &CompileOptions {
            config: top_only.validated().unwrap(),
            ..CompileOptions::default()
        },
    )
    .unwrap()
    .report;
    assert!(
        default.coverage > top.coverage,
        "{} {}",
        default.coverage,
        top.coverage
    );
    assert!(
        default.rendered_coverage >= 0.8 * top.rendered_coverage,
        "played {:.2}, with splitting on the top only {:.2}",
        default.rendered_coverage,
        top.rendered_coverage
    );
}

/// Fast touch under the default, measured by `touchc trade --cases`'s runner: three
/// swipes at 2.5 m/s stay three trajectories on both sensors and rates, and a rub at
/// 1 m/s is followed by one trajectory. A flat hand's reported point moves faster than
/// the hand (a maximum pinned at the sensor's edge, then a cell at once), so a gate at
/// the hand's own speed cuts it into pieces; and its lattice points, cells fixed on the
/// sensor, must not hop from cell to cell, or the flow trades the hand's own trajectory
/// for theirs at every turn of the rub.
#[test]
fn fast_swipes_and_a_vigorous_rub_stay_whole_under_the_default() {
    use touchc_eval::cases::run_case;
    let configs = [(Preset::Touch, ValidConfig::preset(Preset::Touch))];
    let mut failures = Vec::new();
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for rate in synth::cases::RATES_HZ {
            for case in synth::cases::cases_on(sensor, rate) {
                let swipes = case.name.starts_with("3 swipes");
                let rub = case.name == "rub 1 m/s";
                if !(swipes || rub) {
                    continue;
                }
                let rows = run_case(&case, 1, &CompileOptions::default(), &configs).unwrap();
                let row = &rows[0];
                let ok = row.passes() && (!swipes || row.trajectories == 3);
                if !ok {
                    failures.push(format!(
                        "{} {rate} Hz {}: {row:?}",
                        sensor.name(),
                        case.name
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
