//! The network against finite differences of its loss and against its definition
//! computed one output at a time.

use super::*;

/// Widths small enough for the tests' recordings of a dozen frames.
const SMALL: Arch = Arch {
    c1: 3,
    c2: 4,
    c3: 5,
    k3: 2,
};

/// The analytic gradient matches a finite difference of the loss for a few weights
/// of every layer.
#[test]
fn gradients_match_finite_differences() {
    let mut rng = Rng::new(3);
    let frames = ndarray::Array3::from_shape_fn((13, 7, 8), |_| rng.uniform() as f32);
    let sample = Sample {
        frames,
        rate_hz: 20.0,
        pitch_mm: 25.4,
    };
    let mut net = Net::new(13, 7, 8, 3, SMALL, 5);
    // Biases off zero so every ReLU is away from its kink for a small step.
    for p in net.params.iter_mut() {
        *p += 0.05;
    }
    let x = net.input_of(&sample);
    let (_, g) = net.backward(&x, &net.forward(&x), 1);
    let o = offsets(net.arch, 3);
    for j in [
        0,
        2,
        o.b1,
        o.w2 + 3,
        o.b2 + 1,
        o.w3 + 4,
        o.b3 + 2,
        o.wd + 2,
        o.wd + 9,
        o.bd,
    ] {
        let h = 1e-2f32;
        let mut up = net.clone();
        up.params[j] += h;
        let mut down = net.clone();
        down.params[j] -= h;
        let lu = -up.forward(&x).probs[1].ln();
        let ld = -down.forward(&x).probs[1].ln();
        let numeric = (lu - ld) / (2.0 * h);
        assert!(
            (numeric - g[j]).abs() < 2e-3 + 0.05 * g[j].abs(),
            "weight {j}: {numeric} vs {}",
            g[j]
        );
    }
}

/// The network as its definition reads, one output at a time: Keras's Conv3D
/// (1, 2, 2) "valid" with ReLU, MaxPooling3D (2, 2, 2), twice; Conv3D (k3, 1, 1)
/// "valid" with ReLU; GlobalAveragePooling3D and GlobalMaxPooling3D concatenated;
/// Dense, softmax.
fn reference(net: &Net, x: &[f32]) -> Vec<f32> {
    let (a, o) = (net.arch, offsets(net.arch, net.classes));
    let p = &net.params;
    let conv = |x: &[f32], d: Dims, w: &[f32], b: &[f32], cout: usize| {
        let (h, wd) = (d.h - 1, d.w - 1);
        let mut y = vec![0.0f32; cout * d.t * h * wd];
        for co in 0..cout {
            for t in 0..d.t {
                for i in 0..h {
                    for j in 0..wd {
                        let mut v = b[co];
                        for ci in 0..d.c {
                            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                                let k = w[((co * d.c + ci) * 2 + dy) * 2 + dx];
                                v += k * x[((ci * d.t + t) * d.h + i + dy) * d.w + j + dx];
                            }
                        }
                        y[((co * d.t + t) * h + i) * wd + j] = v.max(0.0);
                    }
                }
            }
        }
        (
            y,
            Dims {
                c: cout,
                t: d.t,
                h,
                w: wd,
            },
        )
    };
    let pool = |x: &[f32], d: Dims| {
        let o = Dims {
            c: d.c,
            t: d.t / 2,
            h: d.h / 2,
            w: d.w / 2,
        };
        let mut y = vec![f32::NEG_INFINITY; o.len()];
        for c in 0..o.c {
            for t in 0..2 * o.t {
                for i in 0..2 * o.h {
                    for j in 0..2 * o.w {
                        let k = ((c * o.t + t / 2) * o.h + i / 2) * o.w + j / 2;
                        y[k] = y[k].max(x[((c * d.t + t) * d.h + i) * d.w + j]);
                    }
                }
            }
        }
        (y, o)
    };
    let (a1, d1) = conv(x, net.input, &p[..o.b1], &p[o.b1..o.w2], a.c1);
    let (p1, d1) = pool(&a1, d1);
    let (a2, d2) = conv(&p1, d1, &p[o.w2..o.b2], &p[o.b2..o.w3], a.c2);
    let (p2, d2) = pool(&a2, d2);
    // The time convolution and the global pooling of each of its channels.
    let (w3, b3) = (&p[o.w3..o.b3], &p[o.b3..o.wd]);
    let t3 = d2.t + 1 - a.k3;
    let mut g = vec![0.0f32; 2 * a.c3];
    g[a.c3..].iter_mut().for_each(|v| *v = f32::NEG_INFINITY);
    for co in 0..a.c3 {
        for t in 0..t3 {
            for i in 0..d2.h {
                for j in 0..d2.w {
                    let mut v = b3[co];
                    for ci in 0..d2.c {
                        for dt in 0..a.k3 {
                            let k = w3[(co * d2.c + ci) * a.k3 + dt];
                            v += k * p2[((ci * d2.t + t + dt) * d2.h + i) * d2.w + j];
                        }
                    }
                    let v = v.max(0.0);
                    g[co] += v / (t3 * d2.h * d2.w) as f32;
                    g[a.c3 + co] = g[a.c3 + co].max(v);
                }
            }
        }
    }
    let mut z: Vec<f32> = (0..net.classes)
        .map(|k| {
            let row = &p[o.wd + k * g.len()..][..g.len()];
            p[o.bd + k] + row.iter().zip(&g).map(|(a, b)| a * b).sum::<f32>()
        })
        .collect();
    softmax(&mut z);
    z
}

/// The strided, whole-channel layers compute what the definition says, on shapes
/// with odd frames, rows and columns (the floors of the pooling).
#[test]
fn the_network_matches_its_definition() {
    let mut rng = Rng::new(11);
    for (t, h, w) in [(9, 7, 8), (12, 8, 21), (17, 10, 13), (31, 10, 10)] {
        let frames = ndarray::Array3::from_shape_fn((t, h, w), |_| rng.uniform() as f32);
        let sample = Sample {
            frames,
            rate_hz: 20.0,
            pitch_mm: 25.4,
        };
        let mut net = Net::new(t, h, w, 4, SMALL, 7);
        for p in net.params.iter_mut() {
            *p += 0.02;
        }
        let x = net.input_of(&sample);
        let fast = net.forward(&x).probs;
        let slow = reference(&net, &x);
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a - b).abs() < 1e-5, "{t}x{h}x{w}: {fast:?} vs {slow:?}");
        }
    }
}

/// The same touch somewhere else along the arm and later in the recording scores the
/// same: the network reads what a touch is, not where or when (moved by whole strides
/// of the two poolings, 4 frames and 4 cells, with quiet all around it).
#[test]
fn a_touch_moved_in_time_and_space_scores_the_same() {
    let mut rng = Rng::new(21);
    let (t, h, w) = (64, 8, 21);
    let mut first = ndarray::Array3::<f32>::zeros((t, h, w));
    let mut moved = first.clone();
    for dt in 0..16 {
        for r in 2..6 {
            for c in 0..4 {
                let v = rng.uniform() as f32;
                first[[8 + dt, r, 6 + c]] = v;
                moved[[8 + 24 + dt, r, 6 + 4 + c]] = v;
            }
        }
    }
    let sample = |frames| Sample {
        frames,
        rate_hz: 20.0,
        pitch_mm: 25.4,
    };
    let net = Net::new(t, h, w, 3, SMALL, 4);
    let (a, b) = (net.predict(&sample(first)), net.predict(&sample(moved)));
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-5, "{a:?} vs {b:?}");
    }
    assert!(
        a.iter().any(|p| (p - 1.0 / 3.0).abs() > 1e-3),
        "{a:?}: a network that reads nothing"
    );
}

/// The trained weights are the mean of the weights at the end of each averaged epoch:
/// training stops at the same weights whatever the number of epochs to come, so the
/// runs of 3 and 4 epochs without averaging give the two epochs a run of 4 averages
/// from its 3rd.
#[test]
fn trained_weights_are_the_mean_of_the_averaged_epochs() {
    let (samples, labels) = tiny_set();
    let refs: Vec<&Sample> = samples.iter().collect();
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let control = Control {
        cancel: &cancel,
        progress: &|_| {},
    };
    let run = |epochs, average_from| {
        train_averaged(&refs, &labels, 3, (5, epochs, average_from), None, &control)
            .map(|net| net.params)
            .unwrap_or_default()
    };
    let (third, fourth, averaged) = (run(3, usize::MAX), run(4, usize::MAX), run(4, 3));
    assert!(!averaged.is_empty() && third != fourth);
    for ((a, b), m) in third.iter().zip(&fourth).zip(&averaged) {
        let mean = (f64::from(*a) + f64::from(*b)) / 2.0;
        assert!(
            (f64::from(*m) - mean).abs() <= 1e-6 * mean.abs().max(1.0),
            "{m} vs {mean}"
        );
    }
    // The ensemble's first network is the seed's own, averaged over the second half:
    // for 4 epochs, the 3rd and 4th.
    let settings = Settings {
        kind: crate::ScorerKind::Cnn,
        seed: 5,
        epochs: 4,
    };
    let first = train_ensemble(&refs, &labels, 3, &settings, None, &control)
        .map(|nets| nets.into_iter().next().map(|net| net.params));
    assert_eq!(first.ok().flatten(), Some(averaged));
}

/// Six random recordings of 40 frames of 8 x 8 cells, classes 0, 1, 2 twice.
fn tiny_set() -> (Vec<Sample>, [usize; 6]) {
    let mut rng = Rng::new(9);
    let samples = (0..6)
        .map(|_| Sample {
            frames: ndarray::Array3::from_shape_fn((40, 8, 8), |_| rng.uniform() as f32),
            rate_hz: 20.0,
            pitch_mm: 25.4,
        })
        .collect();
    (samples, [0, 1, 2, 0, 1, 2])
}

/// The ensemble is [`NETWORKS`] networks of their own seeds, the first the seed's own
/// network (averaged over the second epoch of two), and it scores the mean of their probabilities; every network reports its
/// epochs under its own number.
#[test]
fn an_ensemble_is_the_mean_of_its_networks() {
    let (samples, labels) = tiny_set();
    let refs: Vec<&Sample> = samples.iter().collect();
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let seen = std::sync::Mutex::new(Vec::new());
    let record = |p: Progress| {
        if let Ok(mut seen) = seen.lock() {
            seen.push((p.network, p.networks, p.epoch));
        }
    };
    let control = Control {
        cancel: &cancel,
        progress: &record,
    };
    let settings = Settings {
        kind: crate::ScorerKind::Cnn,
        seed: 11,
        epochs: 2,
    };
    let nets = train_ensemble(&refs, &labels, 3, &settings, None, &control).unwrap_or_default();
    assert_eq!(nets.len(), NETWORKS);
    let reported = seen.lock().map(|s| s.clone()).unwrap_or_default();
    let want: Vec<(usize, usize, usize)> = (1..=NETWORKS)
        .flat_map(|m| (1..=2).map(move |e| (m, NETWORKS, e)))
        .collect();
    assert_eq!(reported, want);
    let quiet = Control {
        cancel: &cancel,
        progress: &|_| {},
    };
    let alone = train_averaged(&refs, &labels, 3, (11, 2, 2), None, &quiet).map(|n| n.params);
    assert_eq!(alone.ok().as_ref(), Some(&nets[0].params));
    assert!(nets[1].params != nets[0].params && nets[2].params != nets[1].params);
    for sample in &samples {
        let mean = predict_ensemble(&nets, sample);
        let each: Vec<Vec<f64>> = nets.iter().map(|n| n.predict(sample)).collect();
        for (c, m) in mean.iter().enumerate() {
            let want = each.iter().map(|p| p[c]).sum::<f64>() / NETWORKS as f64;
            assert!((m - want).abs() < 1e-12, "{m} vs {want}");
        }
        assert!((mean.iter().sum::<f64>() - 1.0).abs() < 1e-6);
    }
}
