//! Tests of stage 6. Reference numbers marked "scipy" were made with scipy 1.17.1 /
//! numpy 2.x in a throw-away venv (`pip install scipy`), by the one-liners quoted beside
//! them; nothing here needs Python to run.

use super::filter::{settle_frames, SETTLE_TOLERANCE};
use super::pchip::resampled_len;
use super::*;
use sci_rs::signal::filter::design::Sos;
use touchc_model::config::RingOut;

const PRE: f64 = -0.9;
const PEAK: f64 = 1.0;

fn cfg() -> SignalConfig {
    SignalConfig::default()
}

/// Conditions at 20 Hz with the paper's config, causal or zero-phase.
fn run(psi: &[Vec<f64>; CHANNELS], zero_phase: bool) -> Conditioned {
    let cfg = SignalConfig {
        zero_phase,
        ..cfg()
    };
    condition(psi, &cfg, 20.0).unwrap()
}

fn silent(frames: usize) -> [Vec<f64>; CHANNELS] {
    std::array::from_fn(|_| vec![0.0; frames])
}

/// A scene of smooth presses at random places and times on every channel, with silence
/// between them: the shape of the paper's data.
fn scene(frames: usize, seed: u64) -> [Vec<f64>; CHANNELS] {
    let mut rng = touchc_test_rng::Xorshift::mixed(seed);
    let mut psi = silent(frames);
    for x in psi.iter_mut() {
        let mut t = (rng.uniform() * 20.0) as usize;
        while t < frames {
            let len = 3 + (rng.uniform() * 30.0) as usize;
            let height = 0.1 + rng.uniform() * 2.0;
            for k in 0..len.min(frames - t) {
                x[t + k] = height * (std::f64::consts::PI * (k as f64 + 0.5) / len as f64).sin();
            }
            t += len + (rng.uniform() * 40.0) as usize;
        }
    }
    psi
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

// ---------------------------------------------------------------- filter design

/// scipy: `butter(5, 4, fs=20, output='sos')`, printed with `repr(float(v))`.
const SCIPY_SOS_20HZ: [[f64; 6]; 3] = [
    [
        0.02193962068846417,
        0.04387924137692834,
        0.02193962068846417,
        1.0,
        -0.15838444032453627,
        0.0,
    ],
    [1.0, 2.0, 1.0, 1.0, -0.3492860258606905, 0.13031332327594414],
    [1.0, 1.0, 0.0, 1.0, -0.4776547730940111, 0.5457233155094577],
];

/// scipy: `butter(5, 4, fs=1000, output='sos')`.
const SCIPY_SOS_1KHZ: [[f64; 6]; 3] = [
    [
        3.0095543655361253e-10,
        6.019108731072251e-10,
        3.0095543655361253e-10,
        1.0,
        -0.9751778761806492,
        0.0,
    ],
    [1.0, 2.0, 1.0, 1.0, -1.9595298161253178, 0.9601488521391506],
    [1.0, 1.0, 0.0, 1.0, -1.9839616730994816, 0.9845884273930912],
];

fn assert_sos(sos: &[Sos<f64>], reference: &[[f64; 6]; 3]) {
    assert_eq!(sos.len(), 3);
    for (s, r) in sos.iter().zip(reference) {
        let got = [s.b[0], s.b[1], s.b[2], s.a[0], s.a[1], s.a[2]];
        for (g, w) in got.iter().zip(r) {
            assert!(
                (g - w).abs() <= 1e-12 * w.abs().max(1e-300) + 1e-15,
                "{got:?} vs {r:?}"
            );
        }
    }
}

#[test]
fn design_matches_scipy_at_20_hz_and_1_khz() {
    assert_sos(&design_lowpass(5, 4.0, 20.0).unwrap(), &SCIPY_SOS_20HZ);
    assert_sos(&design_lowpass(5, 4.0, 1000.0).unwrap(), &SCIPY_SOS_1KHZ);
}

#[test]
fn unrealisable_filters_are_errors_not_panics() {
    for (order, hz, fs) in [
        (0, 4.0, 20.0),
        (17, 4.0, 20.0),
        (5, 10.0, 20.0),
        (5, 0.0, 20.0),
        (5, -1.0, 20.0),
        (5, f64::NAN, 20.0),
        (5, 4.0, f64::INFINITY),
        (5, 4.0, 0.0),
    ] {
        assert!(matches!(
            design_lowpass(order, hz, fs),
            Err(ConditionError::InvalidFilter { .. })
        ));
    }
}

// ---------------------------------------------------------------- filtering

fn reference_input() -> Vec<f64> {
    let mut x = vec![0.0; 40];
    x[5..13].copy_from_slice(&[1.0, 3.0, 2.0, 5.0, 4.0, 0.0, 0.0, 1.0]);
    x
}

/// scipy: `x = zeros(40); x[5:13] = [1,3,2,5,4,0,0,1]; y = sosfilt(sos, x)`.
const SCIPY_CAUSAL: [(usize, f64); 10] = [
    (0, 0.0),
    (5, 0.02193962068846417),
    (6, 0.19713462751227004),
    (8, 1.7771920305537972),
    (10, 3.748517348245981),
    (12, 2.438111392518229),
    (15, -0.21298381516708037),
    (20, -0.09235677723219257),
    (30, -0.005324295826327765),
    (39, -0.00038740554839794886),
];

/// scipy: `z = sosfilt(sos, sosfilt(sos, x)[::-1])[::-1]` (forward-backward from zero
/// state, no padding: what [`lowpass`] does with `zero_phase`).
const SCIPY_ZERO_PHASE: [(usize, f64); 10] = [
    (0, 0.025490865729587257),
    (5, 0.9673287712169678),
    (6, 2.3467171344851),
    (8, 3.9465688527734084),
    (10, 1.427443013836486),
    (12, -0.014983213116716451),
    (15, 0.08280426247695098),
    (20, 0.02086360236749038),
    (30, 0.001197166458694116),
    (39, -8.499530784457447e-06),
];

#[test]
fn causal_and_zero_phase_filtering_match_scipy() {
    let sos = design_lowpass(5, 4.0, 20.0).unwrap();
    let x = reference_input();
    let y = lowpass(&x, &sos, false);
    let z = lowpass(&x, &sos, true);
    for (i, want) in SCIPY_CAUSAL {
        assert!(close(y[i], want, 1e-12), "causal[{i}] = {} vs {want}", y[i]);
    }
    for (i, want) in SCIPY_ZERO_PHASE {
        assert!(
            close(z[i], want, 1e-12),
            "zero-phase[{i}] = {} vs {want}",
            z[i]
        );
    }
}

/// scipy: `sosfilt(sos, ones(200)).max() - 1` for the 20 Hz design.
const OVERSHOOT_20HZ: f64 = 0.15882033382911098;
/// scipy: `sosfilt(sos, ones(10000)).max() - 1` for the 1 kHz design.
const OVERSHOOT_1KHZ: f64 = 0.12778795243983843;

/// Step responses: the paper's causal filter overshoots (scipy: `sosfilt(sos, ones(N))`
/// max - 1), settles, and stays settled; in f64 SOS that holds at 1 kHz too, where the
/// 4 Hz poles sit within 0.016 of z = 1.
#[test]
fn step_response_overshoots_then_settles_at_20_hz_and_1_khz() {
    for (fs, overshoot) in [(20.0, OVERSHOOT_20HZ), (1000.0, OVERSHOOT_1KHZ)] {
        let sos = design_lowpass(5, 4.0, fs).unwrap();
        let n = 100_000;
        let y = lowpass(&vec![1.0; n], &sos, false);
        let max = y.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
        assert!(
            close(max - 1.0, overshoot, 1e-9),
            "fs {fs}: overshoot {}",
            max - 1.0
        );
        assert!((0.12..=0.16).contains(&(max - 1.0)));
        // Settled after 10 s and still settled 100,000 samples in (no drift).
        let settled_from = (10.0 * fs) as usize;
        assert!(
            y[settled_from..].iter().all(|v| (v - 1.0).abs() < 1e-9),
            "fs {fs}"
        );
        assert!((y[n - 1] - 1.0).abs() < 1e-12);
    }
}

/// Zero phase: a step through the forward-backward pass overshoots less (scipy, zero
/// padded: `x = r_[zeros(200), ones(400), zeros(200)]`, max of the forward-backward
/// output - 1), is symmetric about the middle of a symmetric input, and a 4 Hz sine
/// comes out at exactly half amplitude (|H|^2 at the cut-off) without delay.
#[test]
fn zero_phase_is_symmetric_and_undelayed() {
    let sos = design_lowpass(5, 4.0, 20.0).unwrap();
    let mut x = vec![0.0; 800];
    x[200..600].fill(1.0);
    let z = lowpass(&x, &sos, true);
    let max = z.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
    assert!(close(max - 1.0, 0.08699097674271483, 1e-9), "{}", max - 1.0);
    for k in 0..400 {
        assert!(close(z[200 + k], z[599 - k], 1e-9), "asymmetric at {k}");
    }
    let n = 2000;
    let sine: Vec<f64> = (0..n)
        .map(|t| (2.0 * std::f64::consts::PI * 4.0 * t as f64 / 20.0 + 0.3).sin())
        .collect();
    let z = lowpass(&sine, &sos, true);
    let y = lowpass(&sine, &sos, false);
    for t in 500..1500 {
        assert!(
            close(z[t], 0.5 * sine[t], 1e-9),
            "t {t}: {} vs {}",
            z[t],
            0.5 * sine[t]
        );
    }
    // The causal pass at the cut-off has a phase lag, so it is not a scaled copy.
    assert!((500..1500).any(|t| (y[t] - std::f64::consts::FRAC_1_SQRT_2 * sine[t]).abs() > 0.1));
}

// ---------------------------------------------------------------- spikes

#[test]
fn spike_rule_needs_both_rise_and_drop_above_the_share_of_the_range() {
    let mut ch = silent(0);
    ch[0] = vec![0.0, 0.0, 1.0, 0.0, 0.0]; // range 1, threshold 1/8
    ch[1] = vec![0.0, 1.0, 0.95, 0.9, 0.0]; // an onset that eases off: kept
    ch[2] = vec![0.5, 0.6, 0.5, 0.5, 0.5]; // rise and drop 0.1 < 0.125: kept
    ch[3] = vec![0.2, 0.4, 0.8, 0.6, 0.6]; // rises 0.4, drops 0.2: spike
    ch[4] = vec![0.0, 0.125, 0.0, 0.0, 0.0]; // exactly the threshold: kept
    let before = ch.clone();
    remove_spikes(&mut ch, 1.0 / 8.0);
    assert_eq!(ch[0], vec![0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(ch[1], before[1]);
    assert_eq!(ch[2], before[2]);
    assert_eq!(ch[3], vec![0.2, 0.5, 0.5, 0.5, 0.6]);
    assert_eq!(ch[4], before[4]);
}

#[test]
fn spike_range_is_joint_over_channels() {
    // 0.3 is a spike on its own channel's range but not on the scene's (range 4).
    let mut ch = silent(5);
    ch[0] = vec![0.0, 0.0, 0.3, 0.0, 0.0];
    ch[1] = vec![0.0, 4.0, 4.0, 4.0, 0.0];
    let before = ch.clone();
    remove_spikes(&mut ch, 1.0 / 8.0);
    assert_eq!(ch, before);
    let mut flat = silent(5);
    remove_spikes(&mut flat, 1.0 / 8.0); // zero range: nothing, no NaN
    assert_eq!(flat, silent(5));
}

/// A single 1e6 psi sample amid 1 psi presses is removed before the filter: the scene is
/// normalised on the presses, and the spike's neighbourhood stays at the pre-dent.
#[test]
fn a_single_huge_spike_does_not_set_the_scale() {
    let frames = 200;
    let mut psi = silent(frames);
    for (k, v) in psi[0][10..30].iter_mut().enumerate() {
        *v = (std::f64::consts::PI * k as f64 / 20.0).sin();
    }
    psi[0][150] = 1e6;
    let c = condition(&psi, &cfg(), 20.0).unwrap();
    assert!(c.full_scale_psi < 2.0, "scale {}", c.full_scale_psi);
    let k = c.pad_frames + 150;
    for f in &c.frames_a[k - 5..k + 5] {
        assert!(close(f[0], PRE, 1e-9), "{}", f[0]);
    }
    let max = c
        .output
        .iter()
        .map(|f| f[0])
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(max, PEAK);
}

// ---------------------------------------------------------------- conditioning

fn assert_ramped(c: &Conditioned) {
    let first = c.output[0];
    let last = c.output[c.output.len() - 1];
    assert!(
        first.iter().chain(&last).all(|&v| v == 0.0),
        "{first:?} {last:?}"
    );
    assert!(c.output.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn all_silent_is_exactly_the_pre_dent_between_ramps() {
    for psi in [silent(100), std::array::from_fn(|_| vec![-0.3; 100])] {
        for zero_phase in [false, true] {
            let c = run(&psi, zero_phase);
            assert_ramped(&c);
            assert_eq!(c.full_scale_psi, 0.0);
            let r = c.ramp_samples;
            assert_eq!(r, 500);
            assert!(c.output[r..c.output.len() - r]
                .iter()
                .flatten()
                .all(|&v| v == PRE));
            // Ramps: monotone from 0 A to the pre-dent and back.
            for w in c.output[..=r].windows(2) {
                assert!(w[1][0] <= w[0][0]);
            }
            for w in c.output[c.output.len() - r - 1..].windows(2) {
                assert!(w[1][0] >= w[0][0]);
            }
            assert!(c.frames_a.iter().flatten().all(|&v| v == PRE));
        }
    }
    // An empty recording is the same silent stimulus, not an error.
    let c = condition(&silent(0), &cfg(), 20.0).unwrap();
    assert_ramped(&c);
    assert_eq!(c.frames_a.len(), c.pad_frames + c.tail_frames);
}

/// A constant press on one channel: the causal filter overshoots at the onset, so the
/// overshoot is the peak and the settled plateau sits at `1 / (1 + overshoot)` of the
/// span (scipy's step overshoot at 20 Hz, see above).
#[test]
fn constant_channel_settles_where_the_overshoot_says() {
    let mut psi = silent(400);
    psi[3] = vec![2.0; 400];
    let c = condition(&psi, &cfg(), 20.0).unwrap();
    assert_ramped(&c);
    let plateau = PRE + (PEAK - PRE) / (1.0 + OVERSHOOT_20HZ);
    let mid = c.frames_a[c.pad_frames + 300];
    assert!(close(mid[3], plateau, 1e-9), "{} vs {plateau}", mid[3]);
    assert!(close(c.full_scale_psi, 2.0 * (1.0 + OVERSHOOT_20HZ), 1e-9));
    for ch in (0..CHANNELS).filter(|&ch| ch != 3) {
        assert!(c.frames_a.iter().all(|f| f[ch] == PRE));
    }
    let top = c
        .output
        .iter()
        .map(|f| f[3])
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(top, PEAK);
}

#[test]
fn normalisation_is_scale_invariant_from_1e_minus_30_to_1e30() {
    let base = scene(300, 7);
    let reference = condition(&base, &cfg(), 20.0).unwrap();
    for scale in [1e-30, 1e30, 3.7e-12, 1e300] {
        let psi: [Vec<f64>; CHANNELS] =
            std::array::from_fn(|ch| base[ch].iter().map(|v| v * scale).collect());
        let c = condition(&psi, &cfg(), 20.0).unwrap();
        assert_eq!(c.output.len(), reference.output.len());
        for (a, b) in c
            .output
            .iter()
            .flatten()
            .zip(reference.output.iter().flatten())
        {
            assert!(close(*a, *b, 1e-12), "scale {scale}: {a} vs {b}");
        }
        assert!(close(
            c.full_scale_psi / scale,
            reference.full_scale_psi,
            1e-12
        ));
    }
}

/// The 1 kHz reference stays inside [pre-dent, peak] (PCHIP adds no overshoot), passes
/// every frame-rate value exactly at its own sample, and its steps stay small.
#[test]
fn output_stays_in_range_and_passes_through_the_frames() {
    for zero_phase in [false, true] {
        let c = run(&scene(400, 11), zero_phase);
        assert_ramped(&c);
        let r = c.ramp_samples;
        let body = &c.output[r..c.output.len() - r];
        assert_eq!(body.len(), (c.frames_a.len() - 1) * 50 + 1);
        assert!(body.iter().flatten().all(|&v| (PRE..=PEAK).contains(&v)));
        for (k, f) in c.frames_a.iter().enumerate() {
            assert_eq!(&c.output[c.output_index_of_frame(k)], f);
        }
        let peak = c
            .frames_a
            .iter()
            .flatten()
            .fold(f64::NEG_INFINITY, |m, &v| m.max(v));
        assert_eq!(peak, PEAK);
        let steepest = c
            .output
            .windows(2)
            .flat_map(|w| (0..CHANNELS).map(move |ch| (w[1][ch] - w[0][ch]).abs()))
            .fold(0.0, f64::max);
        assert!(steepest < 0.05, "steepest step {steepest} A/ms");
    }
}

/// Causal filtering delays a press; zero phase keeps its peak where the input's is.
#[test]
fn zero_phase_option_removes_the_delay_of_a_press() {
    let mut psi = silent(200);
    for (k, v) in psi[2][80..121].iter_mut().enumerate() {
        *v = (std::f64::consts::PI * k as f64 / 40.0).sin();
    }
    let argmax = |c: &Conditioned| {
        let f: Vec<f64> = c.frames_a.iter().map(|f| f[2]).collect();
        let max = f.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
        f.iter().position(|&v| v == max).unwrap_or(0) - c.pad_frames
    };
    let causal = run(&psi, false);
    let zero = run(&psi, true);
    assert_eq!(argmax(&zero), 100);
    assert!(argmax(&causal) >= 102, "{}", argmax(&causal));
}

/// 100,000 frames (83 minutes) of a periodic scene: the last period equals the first
/// after the start transient, everything stays finite and in range.
#[test]
fn very_long_signals_do_not_drift() {
    let frames = 100_000;
    let period = 40;
    let one = scene(period, 3);
    let psi: [Vec<f64>; CHANNELS] =
        std::array::from_fn(|ch| (0..frames).map(|t| one[ch][t % period]).collect());
    for zero_phase in [false, true] {
        let c = run(&psi, zero_phase);
        assert_ramped(&c);
        let p = c.pad_frames;
        let early = p + 50 * period;
        let late = p + frames - 50 * period;
        for k in 0..period {
            for ch in 0..CHANNELS {
                let (a, b) = (c.frames_a[early + k][ch], c.frames_a[late + k][ch]);
                assert!(
                    close(a, b, 1e-9),
                    "zero_phase {zero_phase} ch {ch} k {k}: {a} vs {b}"
                );
            }
        }
        assert!(c
            .output
            .iter()
            .flatten()
            .all(|&v| (PRE..=PEAK).contains(&v)));
    }
}

#[test]
fn bad_input_and_config_are_typed_errors() {
    let psi = scene(50, 1);
    let mut nan = psi.clone();
    nan[5][7] = f64::NAN;
    assert_eq!(
        condition(&nan, &cfg(), 20.0),
        Err(ConditionError::NotFinite {
            channel: 5,
            frame: 7
        })
    );
    let mut short = psi.clone();
    short[2].pop();
    assert!(matches!(
        condition(&short, &cfg(), 20.0),
        Err(ConditionError::LengthMismatch { channel: 2, .. })
    ));
    let inverted = SignalConfig {
        pre_dent_a: 1.0,
        peak_a: -0.9,
        ..cfg()
    };
    assert!(matches!(
        condition(&psi, &inverted, 20.0),
        Err(ConditionError::InvalidRange { .. })
    ));
    let fast = SignalConfig {
        lowpass_hz: 12.0,
        ..cfg()
    };
    assert!(matches!(
        condition(&psi, &fast, 20.0),
        Err(ConditionError::InvalidFilter { .. })
    ));
    let ramp = SignalConfig {
        ramp_s: f64::NAN,
        ..cfg()
    };
    assert!(matches!(
        condition(&psi, &ramp, 20.0),
        Err(ConditionError::InvalidParameter { name: "ramp_s", .. })
    ));
    for rate in [0.0, 0.5, 2000.0, f64::NAN] {
        assert!(matches!(
            condition(&psi, &cfg(), rate),
            Err(ConditionError::InvalidParameter {
                name: "frame_rate_hz",
                ..
            })
        ));
    }
    let long_ramp = SignalConfig {
        ramp_s: 61.0,
        ..cfg()
    };
    assert!(matches!(
        condition(&psi, &long_ramp, 20.0),
        Err(ConditionError::InvalidParameter { name: "ramp_s", .. })
    ));
}

// ---------------------------------------------------------------- limits

fn constant(ms: usize, current: f64) -> Vec<[f64; CHANNELS]> {
    // Slow raised-cosine edges so only the level matters.
    let edge = 100;
    (0..ms)
        .map(|t| {
            let w = raised_cosine(t.min(ms - 1 - t).min(edge), edge);
            let mut f = [0.0; CHANNELS];
            f[6] = current * w;
            f
        })
        .collect()
}

#[test]
fn each_limit_is_detected_at_the_right_sample() {
    let limits = Limits::default();
    assert_eq!(check_limits(&constant(1000, 0.9), &limits), Ok(()));
    assert!(matches!(
        check_limits(&constant(1000, 1.2), &limits),
        Err(LimitViolation::Peak { channel: 6, .. })
    ));
    let mut jump = constant(1000, 0.5);
    jump[500][6] += 0.2;
    assert!(matches!(
        check_limits(&jump, &limits),
        Err(LimitViolation::Slew {
            channel: 6,
            sample: 500,
            ..
        })
    ));
    // Ending away from 0 A is a step to 0 A after the last sample.
    let cut = vec![[0.05; CHANNELS], [0.2; CHANNELS]];
    assert!(matches!(
        check_limits(&cut, &limits),
        Err(LimitViolation::Slew { sample: 1, .. })
    ));
    let cut = vec![[0.03; CHANNELS], [0.07; CHANNELS], [0.1; CHANNELS]];
    assert!(matches!(
        check_limits(&cut, &limits),
        Err(LimitViolation::Slew { sample: 3, .. })
    ));
    // Thermal: 1 A fills the bucket at 1 - 0.6^2 A^2 per s: 30 A^2 s last about 47 s.
    let long = constant(60_000, 1.0);
    match check_limits(&long, &limits) {
        Err(LimitViolation::Thermal {
            channel: 6, sample, ..
        }) => {
            let expected = 30.0 / (1.0 - 0.6 * 0.6) * 1000.0;
            assert!(
                (sample as f64 - expected).abs() < 200.0,
                "{sample} vs {expected}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Below the continuous current the bucket never fills, however long.
    assert_eq!(check_limits(&constant(200_000, 0.6), &limits), Ok(()));
}

#[test]
fn thermal_bucket_leaks_and_saturates_at_zero() {
    let limits = Limits {
        thermal_budget_a2s: 0.3,
        ..Limits::default()
    };
    // 1 s at 0.95 A (0.8 s at full level) adds about 0.42 A^2 s: over budget alone...
    let hot = constant(1000, 0.95);
    assert!(matches!(
        check_limits(&hot, &limits),
        Err(LimitViolation::Thermal { .. })
    ));
    // ...but two half-second bursts (about 0.16 A^2 s each) with a rest between them
    // pass: the bucket leaks.
    let mut two = constant(500, 0.95);
    two.extend(std::iter::repeat_n([0.0; CHANNELS], 3000));
    two.extend(constant(500, 0.95));
    assert_eq!(check_limits(&two, &limits), Ok(()));
    // A long rest before cannot bank credit (the bucket stops at 0).
    let mut rested = vec![[0.0; CHANNELS]; 100_000];
    rested.extend(constant(1000, 0.95));
    assert!(matches!(
        check_limits(&rested, &limits),
        Err(LimitViolation::Thermal { .. })
    ));
}

/// The thermal root search against plain bisection on [`check_limits`] (the oracle
/// shares only the limit check with it): the same factor to within 2^-31, on signals
/// whose bucket fills at different times on different channels, some over the peak
/// too.
/// A share of the thermal budget: a signal that passes the whole budget is left alone,
/// one that does not is fitted under the share (the largest factor there, as `fit`
/// finds it against that budget), and share 1 is `fit`.
#[test]
fn fit_to_a_share_of_the_thermal_budget() {
    let limits = Limits::default();
    let share = 0.8;
    let under = Limits {
        thermal_budget_a2s: limits.thermal_budget_a2s * share,
        ..limits
    };
    // 60 s at 0.9 A: about 27 A^2 s in the bucket ((0.81 - 0.36) A^2 a second), under
    // the budget of 30 but over 80% of it.
    let mut warm = constant(60_000, 0.9);
    assert!(check_limits(&warm, &limits).is_ok() && check_limits(&warm, &under).is_err());
    assert_eq!(fit_to(&mut warm, &limits, share, 0.0), Ok(1.0));
    // 80 s: over the whole budget, fitted to 80% of it.
    let hot = constant(80_000, 0.9);
    let mut shared = hot.clone();
    let s = fit_to(&mut shared, &limits, share, 0.0).unwrap();
    let mut alone = hot.clone();
    assert_eq!(fit(&mut alone, &under), Ok(s));
    assert_eq!(check_limits(&shared, &under), Ok(()));
    let mut whole = hot.clone();
    let mut one = hot;
    assert_eq!(
        fit_to(&mut whole, &limits, 1.0, 0.0),
        fit(&mut one, &limits)
    );
}

/// Room for the player's accounting (each tick's current rounded up): a fitted signal's
/// bucket leaks as if every sample carried `accounting` more current, so it is the
/// signal `fit` makes against a continuous rating lowered by `2 accounting peak +
/// accounting^2`; a signal within the real limits is still left alone; a negative or
/// non-finite room is refused.
#[test]
fn fit_to_leaves_room_for_the_players_accounting() {
    let limits = Limits::default();
    let (share, accounting) = (0.96, 0.0012);
    let extra = accounting * (2.0 * limits.peak_a + accounting);
    let slower = Limits {
        thermal_budget_a2s: limits.thermal_budget_a2s * share,
        continuous_a: (limits.continuous_a.powi(2) - extra).sqrt(),
        ..limits
    };
    // 5 minutes at 0.675 A: the real leak (0.36 A^2) leaves 0.0956 A^2 a second, 28.7
    // A^2 s by the end, the slower one 0.0980 (29.4, over 96% of the 30 A^2 s budget):
    // within the budget only at the real rating.
    let mut warm = constant(300_000, 0.675);
    assert!(check_limits(&warm, &limits).is_ok() && check_limits(&warm, &slower).is_err());
    assert_eq!(fit_to(&mut warm, &limits, share, accounting), Ok(1.0));
    // Over the budget at both: fitted as `fit` fits it at the slower leak, which the
    // room costs 0.1% of the factor here.
    let hot = constant(300_000, 0.72);
    let (mut roomy, mut alone, mut tight) = (hot.clone(), hot.clone(), hot);
    let s = fit_to(&mut roomy, &limits, share, accounting).unwrap();
    assert_eq!(fit(&mut alone, &slower), Ok(s));
    assert_eq!(roomy, alone);
    let without = fit_to(&mut tight, &limits, share, 0.0).unwrap();
    assert!(s < without && s > 0.99 * without, "{s} {without}");
    for bad in [-1e-3, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            fit_to(&mut constant(10, 0.5), &limits, share, bad),
            Err(LimitViolation::InvalidLimits {
                name: "accounting_a",
                ..
            })
        ));
    }
}

#[test]
fn fit_agrees_with_bisection_on_thermal_signals() {
    let limits = Limits::default();
    for (k, (seconds, level, second)) in [(40, 1.0, 0.8), (75, 0.9, 0.95), (50, 1.6, 0.7)]
        .into_iter()
        .enumerate()
    {
        let ms = seconds * 1000;
        let mut signal = constant(ms, level);
        for (t, f) in signal.iter_mut().enumerate() {
            // A second channel, hot in the second half only.
            let w = raised_cosine(t.saturating_sub(ms / 2).min(ms - 1 - t).min(100), 100);
            f[2] = second * w;
        }
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        while hi - lo > 1e-12 {
            let mid = 0.5 * (lo + hi);
            let scaled: Vec<_> = signal.iter().map(|f| f.map(|v| v * mid)).collect();
            if check_limits(&scaled, &limits).is_ok() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let mut fitted = signal.clone();
        let s = fit(&mut fitted, &limits).unwrap();
        assert!(
            (s - lo).abs() < 1.0 / 2_147_483_648.0,
            "case {k}: {s} vs {lo}"
        );
        assert_eq!(check_limits(&fitted, &limits), Ok(()), "case {k}");
    }
}

#[test]
fn fit_finds_the_largest_passing_scale() {
    let limits = Limits::default();
    let mut ok = constant(1000, 0.9);
    let copy = ok.clone();
    assert_eq!(fit(&mut ok, &limits), Ok(1.0));
    assert_eq!(ok, copy);

    let mut loud = constant(1000, 2.0);
    let s = fit(&mut loud, &limits).unwrap();
    assert!(close(s, 0.5, 1e-12), "{s}");
    assert_eq!(check_limits(&loud, &limits), Ok(()));

    // Thermal-bound: 60 s at 1 A needs a scale a little below 1.
    let original = constant(60_000, 1.0);
    let mut long = original.clone();
    let s = fit(&mut long, &limits).unwrap();
    assert!(s < 1.0 && s > 0.8, "{s}");
    assert_eq!(check_limits(&long, &limits), Ok(()));
    let over: Vec<_> = original
        .iter()
        .map(|f| f.map(|v| v * s * (1.0 + 1e-9)))
        .collect();
    assert!(check_limits(&over, &limits).is_err());

    let mut nan = constant(10, 0.5);
    nan[3][1] = f64::NAN;
    assert!(matches!(
        fit(&mut nan, &limits),
        Err(LimitViolation::NotFinite {
            channel: 1,
            sample: 3
        })
    ));
    let bad = Limits {
        slew_a_per_ms: -1.0,
        ..limits
    };
    assert!(matches!(
        check_limits(&constant(10, 0.1), &bad),
        Err(LimitViolation::InvalidLimits { .. })
    ));
}

/// The paper's own signals must pass the default limits unchanged: a 705-frame scene
/// (the longest recording of the public data set), both filter modes.
#[test]
fn paper_sized_scenes_pass_the_default_limits() {
    for seed in [1, 2, 3] {
        for zero_phase in [false, true] {
            let c = run(&scene(705, seed), zero_phase);
            assert_eq!(check_limits(&c.output, &Limits::default()), Ok(()));
        }
    }
}

#[test]
fn pchip_stays_between_neighbours_and_is_exact_at_nodes() {
    let y = [0.0, 0.0, 1.0, 1.0, 0.2, 0.9, -0.5, -0.5, 0.3];
    let curve = Pchip::new(&y).unwrap();
    let n = resampled_len(y.len(), 20.0, 1000.0);
    assert_eq!(n, (y.len() - 1) * 50 + 1);
    let out: Vec<f64> = (0..n)
        .map(|j| curve.eval(resampled_position(j, 20.0, 1000.0)))
        .collect();
    for k in 0..y.len() - 1 {
        assert_eq!(out[50 * k], y[k]);
        let (lo, hi) = (y[k].min(y[k + 1]), y[k].max(y[k + 1]));
        assert!(
            out[50 * k..=50 * (k + 1)]
                .iter()
                .all(|&v| v >= lo && v <= hi),
            "piece {k}"
        );
    }
    // Eight curves at once are each curve alone, bit for bit.
    let rows: Vec<Vec<f64>> = (0..CHANNELS)
        .map(|ch| y.iter().map(|v| v * (ch as f64 - 3.5)).collect())
        .collect();
    let curves: [Pchip; CHANNELS] = std::array::from_fn(|ch| Pchip::new(&rows[ch]).unwrap());
    for j in 0..n {
        let u = resampled_position(j, 20.0, 1000.0);
        let all = eval_channels(&curves, u);
        for (ch, c) in curves.iter().enumerate() {
            assert_eq!(all[ch].to_bits(), c.eval(u).to_bits(), "{ch} at {u}");
        }
    }
    // C1: no slope break at the nodes. One-sided difference quotients over 1e-6 of a
    // frame agree to O(1e-6 * curvature); a linear interpolant breaks by up to 1.4 here.
    let eps = 1e-6;
    for k in 1..y.len() - 1 {
        let u = k as f64;
        let left = (curve.eval(u) - curve.eval(u - eps)) / eps;
        let right = (curve.eval(u + eps) - curve.eval(u)) / eps;
        assert!((left - right).abs() < 1e-4, "node {k}: {left} vs {right}");
    }
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    /// Arbitrary scenes: silence, presses, tare residue below zero and lone spikes, on
    /// 8 channels of 1..120 frames.
    fn scenes() -> impl Strategy<Value = [Vec<f64>; CHANNELS]> {
        (1usize..120).prop_flat_map(|frames| {
            let sample = prop_oneof![
                3 => Just(0.0),
                4 => 0.0..3.0f64,
                1 => -0.5..0.0f64,
                1 => 0.0..1e4f64,
            ];
            proptest::collection::vec(proptest::collection::vec(sample, frames), CHANNELS)
                .prop_map(|v| std::array::from_fn(|ch| v[ch].clone()))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Whatever the pressures, the reference starts and ends at 0 A, stays finite and
        /// inside [pre-dent, peak], and passes the default limits unchanged.
        #[test]
        fn output_is_always_a_safe_stimulus(psi in scenes(), zero_phase in any::<bool>()) {
            let c = run(&psi, zero_phase);
            prop_assert!(c.output.first().is_some_and(|f| f.iter().all(|&v| v == 0.0)));
            prop_assert!(c.output.last().is_some_and(|f| f.iter().all(|&v| v == 0.0)));
            prop_assert!(c.output.iter().flatten().all(|&v| (PRE..=PEAK).contains(&v)));
            prop_assert_eq!(check_limits(&c.output, &Limits::default()), Ok(()));
        }

        /// Normalisation divides the scale out: any positive factor gives the same currents.
        #[test]
        fn conditioning_is_scale_invariant(psi in scenes(), exp in -30i32..30) {
            let scale = 10f64.powi(exp);
            let scaled: [Vec<f64>; CHANNELS] =
                std::array::from_fn(|ch| psi[ch].iter().map(|v| v * scale).collect());
            let (a, b) = (run(&psi, false), run(&scaled, false));
            for (x, y) in a.output.iter().flatten().zip(b.output.iter().flatten()) {
                prop_assert!((x - y).abs() <= 1e-9, "{} vs {}", x, y);
            }
        }
    }
}

/// The settle time the early stop finds is the one the whole horizon gives, for the
/// filters the config allows: every order, cutoffs from far below to near Nyquist.
#[test]
fn settle_frames_stops_early_at_the_whole_horizons_answer() {
    let whole = |sos: &[Sos<f64>]| {
        let mut impulse = vec![0.0; 1 << 16];
        impulse[0] = 1.0;
        let h = lowpass(&impulse, sos, false);
        let peak = h.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        h.iter()
            .rposition(|v| v.abs() > SETTLE_TOLERANCE * peak)
            .unwrap_or(0)
            + 1
    };
    for order in [1, 2, 3, 5, 8, 12, 16] {
        for (cutoff_hz, rate_hz) in [(4.0, 20.0), (4.0, 54.0), (0.5, 200.0), (9.0, 20.0)] {
            let sos = design_lowpass(order, cutoff_hz, rate_hz).unwrap();
            assert_eq!(
                settle_frames(&sos),
                whole(&sos),
                "order {order}, {cutoff_hz} Hz at {rate_hz} Hz"
            );
        }
    }
}

/// One channel pressed 1 psi for `press_s` seconds, with `quiet_s` of silence on each
/// side, at `rate` Hz.
fn press(rate: f64, quiet_s: f64, press_s: f64) -> [Vec<f64>; CHANNELS] {
    let quiet = (quiet_s * rate).round() as usize;
    let on = (press_s * rate).round() as usize;
    let mut psi = silent(2 * quiet + on);
    psi[3][quiet..quiet + on].fill(1.0);
    psi
}

#[test]
fn ring_out_in_seconds_lasts_as_long_at_any_rate() {
    let seconds = SignalConfig {
        ring_out: RingOut::Seconds,
        ..cfg()
    };
    for zero_phase in [false, true] {
        let cfg = SignalConfig {
            zero_phase,
            ..seconds.clone()
        };
        // 0.5 + 1 + 0.5 s: 40 frames at 20 Hz, 108 at 54 Hz, 100 at 50 Hz.
        let runs: Vec<Conditioned> = [20.0, 54.0, 50.0]
            .iter()
            .map(|&rate| condition(&press(rate, 0.5, 1.0), &cfg, rate).unwrap())
            .collect();
        let lens: Vec<usize> = runs.iter().map(|c| c.output.len()).collect();
        assert!(
            lens.iter().all(|&n| n.abs_diff(lens[0]) <= 1),
            "zero phase {zero_phase}: {lens:?}"
        );
        for c in &runs {
            // Starts and ends at rest, the pre-dent on either side of the ramps.
            let n = c.output.len();
            assert_eq!((c.output[0], c.output[n - 1]), ([0.0; 8], [0.0; 8]));
            let (a, b) = (c.output[c.ramp_samples], c.output[n - 1 - c.ramp_samples]);
            assert!(
                (a[3] - PRE).abs() < 1e-6 && (b[3] - PRE).abs() < 1e-6,
                "{a:?} {b:?}"
            );
            // The press reaches full scale (between frames, the 1 kHz ticks may miss
            // the frame that holds it by a little).
            let top = c.output.iter().map(|s| s[3]).fold(f64::MIN, f64::max);
            assert!(top <= PEAK && top > PEAK - 0.01, "{top}");
        }
    }
    // The paper's frames differ by rate: its filter settles later at 20 Hz, in
    // coarser frames.
    let paper: Vec<usize> = [20.0, 54.0]
        .iter()
        .map(|&rate| {
            condition(&press(rate, 0.5, 1.0), &cfg(), rate)
                .unwrap()
                .output
                .len()
        })
        .collect();
    assert!(paper[0] > paper[1] + 100, "{paper:?}");
}

#[test]
fn ring_out_in_frames_is_the_papers() {
    // Unchanged: the body runs from the padding frame to the last frame of the tail,
    // through every frame-rate sample.
    let c = run(&press(20.0, 0.5, 1.0), false);
    assert_eq!(c.start_frame, 0.0);
    assert_eq!(c.pad_frames, 1);
    assert_eq!(c.output.len(), 2 * 500 + (c.frames_a.len() - 1) * 50 + 1);
    for k in [0, 7, c.frames_a.len() - 1] {
        assert_eq!(c.output[c.output_index_of_frame(k)], c.frames_a[k]);
    }
}
