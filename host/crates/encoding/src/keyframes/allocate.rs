//! A tolerance per second and channel for a dense file: the RMS budget spent where it
//! saves most bends ([`allocate`]).

use rayon::prelude::*;
use touch_protocol::{stimulus, CHANNELS};

use super::tube::{tube_scheduled, Schedule, WindowCosts};
use super::KeyframeError;

/// Multiples of the uniform tube's tolerance that [`allocate`] chooses among, per
/// window and channel (those over the max bound are left out). Measured on the 166
/// stimuli of `examples/sizes.rs`: 16 factors from 0.5 to 2.6 give a worst case 3% lower
/// than 9 from 0.7 to 1.8.
const ALLOCATE_FACTORS: [f64; 16] = [
    0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.8, 2.0, 2.3, 2.6,
];

/// The window lengths [`allocate`] tries, in units of [`ALLOCATE_UNIT_MS`]: 800 and
/// 1200 ms. The outcome of a schedule is chaotic (a window's lines run on into the
/// next); of the two, the smaller file wins (on the 166 stimuli, 2-4% smaller at the
/// worst case than one window length; 250 and 500 ms windows were larger).
const ALLOCATE_WINDOWS: [usize; 2] = [2, 3];

/// The granularity of the windows, ms.
const ALLOCATE_UNIT_MS: usize = 400;

/// Schedules [`allocate`] plays out per window length, at most.
const ALLOCATE_TRIES: usize = 6;

/// Spends the RMS budget where it saves most bends. The uniform tube at `tol`
/// (fraction of full scale) times each of [`ALLOCATE_FACTORS`] gives, per window and
/// channel, its bends and squared error; each window and channel then takes the factor
/// that minimises `bends + lambda * error`, `lambda` the smallest whose predicted total
/// error meets the RMS bound (a Lagrangian allocation: a busy stretch may stray further
/// where that saves many bends, a quiet one less). The tube is run with those
/// tolerances and its modelled error checked; the prediction errs by a few per cent
/// either way, so the target is lowered after a miss and bisected after a pass. The
/// smallest passing file, if any.
pub(super) fn allocate<'a>(
    signal: &[[f64; CHANNELS]],
    fs_a: f64,
    period: usize,
    shift: u8,
    tol: f64,
    model: (f64, f64),
    builder: &impl Fn(u8) -> stimulus::Builder<'a>,
) -> Result<Option<Vec<u8>>, KeyframeError> {
    let (rms_model, max_model) = model;
    let unit = (ALLOCATE_UNIT_MS / period).max(1);
    let factors: Vec<f64> = ALLOCATE_FACTORS
        .iter()
        .map(|f| f * tol)
        .filter(|&t| t <= max_model)
        .collect();
    let runs = uniform_costs(signal, fs_a, period, shift, unit, &factors);
    let q = 32768.0 * rms_model;
    let budget = q * q * (signal.len() * CHANNELS) as f64;
    let mut best: Option<Vec<u8>> = None;
    for per in ALLOCATE_WINDOWS {
        let costs = Costs::new(&per_window(&runs, per));
        let (mut passed, mut missed): (Option<f64>, Option<f64>) = (None, None);
        let mut target = 0.98 * budget;
        // The choices tried at this window length and whether they passed: a nearby
        // target often makes the same choice, whose tube need not run again (its file,
        // if it passed, is already in `best`).
        let mut tried: Vec<(Vec<[usize; CHANNELS]>, bool)> = Vec::new();
        for _ in 0..ALLOCATE_TRIES {
            let pick = choose(&costs, smallest_lambda(&costs, target)).1;
            let passes = match tried.iter().find(|(p, _)| *p == pick) {
                Some(&(_, passes)) => passes,
                None => {
                    let schedule = Schedule {
                        keyframes: unit * per,
                        tols: pick
                            .iter()
                            .map(|p| p.map(|f| factors[f] * 32768.0))
                            .collect(),
                    };
                    let (keyframes, rms, max, _) =
                        tube_scheduled(signal, fs_a, period, shift, &schedule, false, Some(model));
                    let passes = rms / 32768.0 <= rms_model && max / 32768.0 <= max_model;
                    if passes {
                        let bytes = builder(shift).encode(&keyframes)?;
                        if best.as_ref().is_none_or(|b| bytes.len() < b.len()) {
                            best = Some(bytes);
                        }
                    }
                    tried.push((pick, passes));
                    passes
                }
            };
            if passes {
                passed = Some(target);
            } else {
                missed = Some(target);
            }
            target = match (passed, missed) {
                (Some(p), Some(m)) if p < m => 0.5 * (p + m),
                (Some(_), _) => break,
                (None, _) => 0.93 * target,
            };
        }
    }
    Ok(best)
}

/// The uniform tube at each tolerance of `factors` (fraction of full scale), costed
/// per window of `unit` keyframes (a window of any of [`ALLOCATE_WINDOWS`] is a sum of
/// them: the uniform tube does not depend on the windows). The tubes are independent
/// and most of an allocation's time, so they run on the rayon pool, listed in the
/// order of `factors`: the same costs on any number of threads.
fn uniform_costs(
    signal: &[[f64; CHANNELS]],
    fs_a: f64,
    period: usize,
    shift: u8,
    unit: usize,
    factors: &[f64],
) -> Vec<WindowCosts> {
    factors
        .par_iter()
        .map(|&t| {
            let uniform = Schedule {
                keyframes: unit,
                tols: vec![[t * 32768.0; CHANNELS]],
            };
            tube_scheduled(signal, fs_a, period, shift, &uniform, true, None).3
        })
        .collect()
}

/// The costs of `runs` per window of `per` unit windows.
fn per_window(runs: &[WindowCosts], per: usize) -> Vec<WindowCosts> {
    runs.iter()
        .map(|run| {
            run.chunks(per)
                .map(|chunk| {
                    std::array::from_fn(|c| {
                        chunk
                            .iter()
                            .fold((0, 0.0), |(b, e), w| (b + w[c].0, e + w[c].1))
                    })
                })
                .collect()
        })
        .collect()
}

/// Per window and channel, each factor's bends and squared error, the factors of one
/// window and channel side by side: what [`choose`] scans, some 300 times per
/// allocation (once per lambda tried).
struct Costs {
    /// Factors per window and channel.
    factors: usize,
    /// `(bends, error)` at `(window * CHANNELS + channel) * factors + factor`.
    table: Vec<(f64, f64)>,
}

impl Costs {
    /// The table of `costs` (per factor, per window and channel).
    fn new(costs: &[WindowCosts]) -> Self {
        let windows = costs.first().map_or(0, Vec::len);
        let mut table = Vec::with_capacity(windows * CHANNELS * costs.len());
        for w in 0..windows {
            for c in 0..CHANNELS {
                table.extend(costs.iter().map(|f| (f64::from(f[w][c].0), f[w][c].1)));
            }
        }
        Costs {
            factors: costs.len(),
            table,
        }
    }

    /// Each window and channel's factors, in window then channel order.
    fn options(&self) -> impl Iterator<Item = &[(f64, f64)]> {
        self.table.chunks_exact(self.factors.max(1))
    }
}

/// The factor of `options` (bends and error per factor) that minimises
/// `bends + lambda * error`, the first of equals.
#[inline]
fn cheapest(options: &[(f64, f64)], lambda: f64) -> usize {
    let (mut f, mut least) = (0, f64::INFINITY);
    for (i, &(bends, error)) in options.iter().enumerate() {
        // Never NaN: bends, error and lambda are finite and not negative.
        let cost = bends + lambda * error;
        if cost < least {
            (f, least) = (i, cost);
        }
    }
    f
}

/// The total error predicted at `lambda` ([`choose`]'s, without the choice).
fn predicted(costs: &Costs, lambda: f64) -> f64 {
    let mut total = 0.0;
    for options in costs.options() {
        total += options[cheapest(options, lambda)].1;
    }
    total
}

/// Each window and channel's factor (an index into the factors) at `lambda`: the one
/// that minimises `bends + lambda * error`; and the total error predicted.
fn choose(costs: &Costs, lambda: f64) -> (f64, Vec<[usize; CHANNELS]>) {
    let mut total = 0.0;
    let mut options = costs.options();
    let windows = costs.table.len() / (CHANNELS * costs.factors.max(1));
    let pick: Vec<[usize; CHANNELS]> = (0..windows)
        .map(|_| {
            std::array::from_fn(|_| {
                let here = options.next().unwrap_or_default();
                let f = cheapest(here, lambda);
                total += here[f].1;
                f
            })
        })
        .collect();
    (total, pick)
}

/// The smallest lambda whose choice ([`choose`]) meets `target`, bisected in log10:
/// the error falls as lambda grows.
fn smallest_lambda(costs: &Costs, target: f64) -> f64 {
    let (mut lo, mut hi) = (-40.0f64, 10.0f64);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if predicted(costs, 10f64.powf(mid)) <= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    10f64.powf(hi)
}

#[cfg(test)]
mod tests {
    use super::super::tests::busy;
    use super::*;

    /// The choice as first written: for each window and channel, the first factor of
    /// least cost by `Iterator::min_by`, costed from the per-factor lists.
    fn choose_by_min(costs: &[WindowCosts], lambda: f64) -> (f64, Vec<[usize; CHANNELS]>) {
        let windows = costs.first().map_or(0, Vec::len);
        let mut total = 0.0;
        let pick = (0..windows)
            .map(|w| {
                std::array::from_fn(|c| {
                    let cost = |f: usize| {
                        let (bends, error) = costs[f][w][c];
                        f64::from(bends) + lambda * error
                    };
                    let f = (0..costs.len())
                        .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
                        .unwrap_or(0);
                    total += costs[f][w][c].1;
                    f
                })
            })
            .collect();
        (total, pick)
    }

    /// The table's choice is the lists' choice, and its predicted error the same to the
    /// bit, at every lambda the bisection may try, on the costs of a busy signal.
    #[test]
    fn the_cost_table_chooses_as_the_cost_lists() {
        let signal = busy(12.0);
        let tol = 0.006;
        let factors: Vec<f64> = ALLOCATE_FACTORS.iter().map(|f| f * tol).collect();
        let runs = uniform_costs(&signal, 1.0, 10, 6, 40, &factors);
        for per in ALLOCATE_WINDOWS {
            let lists = per_window(&runs, per);
            let table = Costs::new(&lists);
            let mut distinct = std::collections::BTreeSet::new();
            for step in 0..=500 {
                let lambda = 10f64.powf(-40.0 + 0.1 * f64::from(step));
                let (total, pick) = choose(&table, lambda);
                let (want_total, want_pick) = choose_by_min(&lists, lambda);
                assert_eq!(pick, want_pick, "per {per}, lambda {lambda}");
                assert_eq!(total.to_bits(), want_total.to_bits(), "per {per}");
                assert_eq!(predicted(&table, lambda).to_bits(), want_total.to_bits());
                distinct.insert(pick);
            }
            // The lambdas span many choices, not one.
            assert!(distinct.len() > 20, "{}", distinct.len());
        }
        // The same costs on one thread as on several.
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| uniform_costs(&signal, 1.0, 10, 6, 40, &factors))
        };
        let bits = |runs: &[WindowCosts]| -> Vec<(u32, u64)> {
            runs.iter()
                .flatten()
                .flatten()
                .map(|&(b, e)| (b, e.to_bits()))
                .collect()
        };
        assert_eq!(bits(&on(1)), bits(&runs));
        assert_eq!(bits(&on(3)), bits(&runs));
        // No factors: no choice.
        assert_eq!(choose(&Costs::new(&[]), 1.0), (0.0, Vec::new()));
    }
}
