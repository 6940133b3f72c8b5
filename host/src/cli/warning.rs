//! A compile's warnings in words: the library returns them as values with their
//! figures; here each becomes the sentence a person reads, with the flags to try.

use std::fmt::Write;

use touchc_input::sanity::SanityWarning;
use touchc_input::warning::{ErasedBy, InputWarning, TransposedBy};
use touchc_model::config::{Baseline, Knob};
use touchc_pipeline::compile::Warning;
use touchc_pipeline::coverage::{MissCause, UntrackedBy};

/// The sentence `touchc` prints for `w` (after the recording's name).
pub fn describe(w: &Warning) -> String {
    match w {
        Warning::Input(w) => input(w),
        Warning::Sanity(w) => sanity(w),
        Warning::NoTouch {
            readings,
            threshold_psi,
            min_readings,
        } => format!(
            "no touch: {readings} readings above {threshold_psi} psi (needs more than \
             {min_readings}); the stimulus is silent"
        ),
        Warning::LowCoverage {
            coverage,
            threshold,
            causes,
            touch_tracking,
        } => {
            let mut w = format!(
                "the tracked contacts explain {:.0}% of the touch pressure (coverage \
                 {coverage:.2}, below {threshold}): touch is lost",
                100.0 * coverage,
            );
            for c in causes {
                w.push_str("; ");
                w.push_str(&cause(c, *touch_tracking));
            }
            w
        }
        Warning::TrajectoryLimit {
            trajectories,
            max_trajectories,
            coverage,
        } => format!(
            "the trajectory limit was reached ({trajectories} of {} = {max_trajectories}): \
             contacts beyond it are not tracked; raise it with --max-trajectories (coverage \
             {coverage:.2} says how much touch is explained)",
            Knob::TrackMaxTrajectories
        ),
        Warning::FlowBudget {
            flow_work,
            work_per_edge,
            trajectories,
            coverage,
        } => format!(
            "tracking stopped at its work budget ({flow_work} edges scanned by the \
             min-cost flow, {work_per_edge} per edge of its graph) after {trajectories} \
             trajectories: weaker contacts may be untracked (coverage {coverage:.2}); a \
             scene this dense is usually noise: check the tare, or narrow the link gate \
             with --max-speed-mm-s"
        ),
        Warning::NoTrajectory => "no trajectory was tracked: every actuator stays at rest".into(),
        Warning::SubsetBudget {
            node_budget,
            transforms_inexact,
            transforms_evaluated,
            trajectories,
        } => format!(
            "placement: the trajectory-subset search ran out of its budget of {node_budget} \
             nodes per transform on {transforms_inexact} of {transforms_evaluated} \
             transforms ({trajectories} trajectories; a scene this dense is usually \
             noise): those transforms kept the best subset found, which may not be optimal"
        ),
        Warning::OutsideWorkspaces => {
            "no trajectory passes through an actuator's workspace: silent".into()
        }
        Warning::Shortfall(s) => format!(
            "the sleeve plays {:.0}% of the touch pressure (rendered coverage {:.2}) where \
             the tracked contacts explain {:.0}% (coverage {:.2}): most of the tracked touch \
             falls outside every driven actuator's workspace; try another placement grid \
             (--grid) or a layout with more or larger workspaces (--layout)",
            100.0 * s.rendered,
            s.rendered,
            100.0 * s.tracked,
            s.tracked
        ),
        Warning::Fitted {
            scale,
            refits,
            refit_step,
        } => {
            let mut w = format!(
                "scaled by {scale:.4} ({:.1} dB) to pass the limits",
                20.0 * scale.log10()
            );
            if *refits > 0 {
                let _ = write!(
                    w,
                    " ({refits} steps of {refit_step} after the fit, for the played codes)"
                );
            }
            w
        }
        // A warning this command line does not know yet still reaches the user.
        other => format!("{other:?}"),
    }
}

/// One likely cause of lost touch, with what to try: `--preset touch` where that
/// preset's tracking is not on already.
fn cause(c: &MissCause, touch_tracking: bool) -> String {
    let pct = |v: f64| (100.0 * v).round();
    let touch_or = if touch_tracking {
        "try"
    } else {
        "try --preset touch, or"
    };
    match *c {
        MissCause::Brief {
            share,
            min_frames,
            min_ms,
        } => format!(
            "{}% of the missed touch is in touches shorter than {min_frames} frames \
             ({min_ms:.0} ms), the least a trajectory needs to pay its entry and exit \
             costs: {touch_or} lower --entry-cost and --exit-cost",
            pct(share),
        ),
        MissCause::Untracked { share, why } => {
            let why = match why {
                UntrackedBy::TooFast {
                    speed_p90_mm_s,
                    gate_mm_s,
                } => format!(
                    "the touch moves at up to {:.2} m/s (90th percentile), the link gate \
                     follows {:.2} m/s: {touch_or} a wider link gate (--max-speed-mm-s)",
                    speed_p90_mm_s / 1000.0,
                    gate_mm_s / 1000.0
                ),
                UntrackedBy::Dropouts { count } => format!(
                    "the touch drops out for one or two frames {count} times (flicker) and \
                     the pieces are too short to track: try --preset touch (links across \
                     missing frames)"
                ),
                UntrackedBy::Weak => format!(
                    "its detections are too weak to start a trajectory: {touch_or} lower \
                     --entry-cost and --exit-cost"
                ),
            };
            format!(
                "{}% of the missed touch is in frames where no contact was tracked; {why}",
                pct(share)
            )
        }
        MissCause::Beside {
            share,
            radius_cells,
        } => format!(
            "{}% of the missed touch lies more than {radius_cells} cells from the contact \
             tracked in its frame: a large contact (a flat hand) or a second one; {}",
            pct(share),
            if touch_tracking {
                format!(
                    "contacts are tracked whole already: try a lower footprint threshold \
                     (--set {}=0.02) or, with contact splitting, a finer lattice (--set {}=1)",
                    Knob::TrackRegionsFootprintPsi,
                    Knob::DetectSplitSpacingCells
                )
            } else {
                "try --preset touch (contacts as regions)".to_string()
            }
        ),
    }
}

/// A recording that looks wrong, and how to put it right.
fn sanity(w: &SanityWarning) -> String {
    match *w {
        SanityWarning::RawCounts { median } => format!(
            "the median reading is {median:.0}, but psi from a skin-touch sensor is rarely \
             above 10: these look like raw ADC counts; convert them to psi before compiling"
        ),
        SanityWarning::FallsWithTouch {
            below,
            above,
            threshold_psi,
            deepest,
        } => format!(
            "pressure seems to fall with touch: {below} readings lie more than \
             {threshold_psi} below their cell's resting level (down to {deepest:.3}) against \
             {above} above it; if the sensor's reading falls with pressure, convert it so \
             that touch is positive psi (e.g. rest minus reading, scaled to psi)"
        ),
        SanityWarning::TouchInTareWindow {
            cells,
            highest_psi,
            tare_s,
            frames,
        } => format!(
            "touch in the tare window: {cells} cell(s) read up to {highest_psi:.3} psi above \
             their resting level during the first {tare_s} s ({frames} frames), which the \
             leading baseline subtracts from the whole recording; if the recording begins \
             mid-touch, try --set {}=robust",
            Knob::InputBaseline
        ),
        SanityWarning::ImplausibleSpeed {
            median_mm_s,
            rate_hz,
            pitch_mm,
        } => format!(
            "the touch moves at a median {:.1} m/s at {rate_hz} Hz and {pitch_mm} mm cells, \
             while hands rarely exceed 1.5 m/s: if the recording's rate is lower or its \
             cells are smaller, give them with --rate / --pitch-mm",
            median_mm_s / 1000.0,
        ),
        SanityWarning::SingleFrameTouches { touches, rate_hz } => format!(
            "all {touches} touches last a single frame ({:.0} ms at {rate_hz} Hz), while \
             taps last 50 ms and more: if the recording's rate is higher, give it with \
             --rate",
            1000.0 / rate_hz,
        ),
        ref other => format!("{other:?}"),
    }
}

/// A count with its noun, singular or plural.
fn count(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

/// The input stage's note on the recording's shape or tare.
fn input(w: &InputWarning) -> String {
    let mut f = String::new();
    match w {
        InputWarning::NanInTareWindow {
            tare_frames,
            cells,
            readings,
            unread_cells,
            quantile,
        } => {
            let _ = write!(
                f,
                "{} missing (NaN) in the tare window (the first {}) of {}: each is tared by \
                 the mean of the readings it has there",
                count(*readings, "reading"),
                count(*tare_frames, "frame"),
                count(*cells, "cell"),
            );
            if *unread_cells > 0 {
                let _ = write!(
                    f,
                    ", and the {} with none there by its {quantile} quantile over the whole \
                     recording",
                    count(*unread_cells, "cell"),
                );
            }
        }
        InputWarning::LikelyTransposed { shape, reason } => {
            let [a, b, c] = *shape;
            let _ = write!(
                f,
                "the array {a} x {b} x {c} is read as {} of {b} x {c} cells, but ",
                count(a, "frame")
            );
            let _ = match reason {
                TransposedBy::LastAxisLongest => {
                    write!(f, "its last axis ({c}) is far longer than the others")
                }
                TransposedBy::SleeveGridFirst => {
                    write!(f, "its first two axes are the sleeve's {a} x {b} cells")
                }
            };
            f.push_str(
                ": if it was saved as [rows, cols, frames], save it as [frames, rows, cols] \
                 (numpy: np.moveaxis(a, -1, 0))",
            );
        }
        InputWarning::TareErasedTouch {
            baseline,
            frames,
            raw_touch_readings,
            highest_psi,
            cause,
        } => {
            let _ = write!(
                f,
                "the tare removed the touch: the raw frames hold {} up to {highest_psi:.3} psi \
                 above the rest of their frame, the tared ones none, so the stimulus is \
                 silent; ",
                count(*raw_touch_readings, "touch reading"),
            );
            let _ = match (cause, baseline) {
                (ErasedBy::TooShort { needed }, _) => write!(
                    f,
                    "{} is too short to tell a cell's rest from its touch: record at least \
                     {needed} frames, with rest before or after the touch",
                    count(*frames, "frame"),
                ),
                (ErasedBy::TouchInTareWindow, _) => write!(
                    f,
                    "the recording begins mid-touch and the leading baseline subtracts the \
                     first seconds from all of it: use the default preset (touch) or --set \
                     {}=robust",
                    Knob::InputBaseline
                ),
                (ErasedBy::TouchThroughout, Baseline::Leading) => write!(
                    f,
                    "the touch is held from the tare window on: use the default preset \
                     (touch) or --set {}=robust, and record rest before or after the touch",
                    Knob::InputBaseline
                ),
                (ErasedBy::TouchThroughout, Baseline::Robust) => write!(
                    f,
                    "each touched cell is pressed for most of the recording, so its low \
                     quantile ({}) is the touch: record rest before or after the touch",
                    Knob::InputBaselineQuantile
                ),
            };
        }
        other => {
            let _ = write!(f, "{other:?}");
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use touchc_pipeline::rendered::Shortfall;

    /// Each warning in the words `touchc` has always printed for it, figure for figure.
    #[test]
    fn every_warning_reads_as_the_command_line_words_it() {
        let cases = [
            (
                Warning::NoTouch {
                    readings: 4,
                    threshold_psi: 0.08,
                    min_readings: 5,
                },
                "no touch: 4 readings above 0.08 psi (needs more than 5); the stimulus is silent",
            ),
            (
                Warning::TrajectoryLimit {
                    trajectories: 1,
                    max_trajectories: 1,
                    coverage: 0.0812,
                },
                "the trajectory limit was reached (1 of track.max_trajectories = 1): contacts \
                 beyond it are not tracked; raise it with --max-trajectories (coverage 0.08 \
                 says how much touch is explained)",
            ),
            (
                Warning::FlowBudget {
                    flow_work: 123_456,
                    work_per_edge: 128,
                    trajectories: 7,
                    coverage: 0.456,
                },
                "tracking stopped at its work budget (123456 edges scanned by the min-cost \
                 flow, 128 per edge of its graph) after 7 trajectories: weaker contacts may be \
                 untracked (coverage 0.46); a scene this dense is usually noise: check the \
                 tare, or narrow the link gate with --max-speed-mm-s",
            ),
            (
                Warning::NoTrajectory,
                "no trajectory was tracked: every actuator stays at rest",
            ),
            (
                Warning::SubsetBudget {
                    node_budget: 5000,
                    transforms_inexact: 3,
                    transforms_evaluated: 40,
                    trajectories: 90,
                },
                "placement: the trajectory-subset search ran out of its budget of 5000 nodes \
                 per transform on 3 of 40 transforms (90 trajectories; a scene this dense is \
                 usually noise): those transforms kept the best subset found, which may not \
                 be optimal",
            ),
            (
                Warning::OutsideWorkspaces,
                "no trajectory passes through an actuator's workspace: silent",
            ),
            (
                Warning::Shortfall(Shortfall {
                    tracked: 0.93,
                    rendered: 0.1234,
                }),
                "the sleeve plays 12% of the touch pressure (rendered coverage 0.12) where the \
                 tracked contacts explain 93% (coverage 0.93): most of the tracked touch falls \
                 outside every driven actuator's workspace; try another placement grid \
                 (--grid) or a layout with more or larger workspaces (--layout)",
            ),
            (
                Warning::Fitted {
                    scale: 0.91476,
                    refits: 0,
                    refit_step: 0.99,
                },
                "scaled by 0.9148 (-0.8 dB) to pass the limits",
            ),
            (
                Warning::Fitted {
                    scale: 0.9138,
                    refits: 1,
                    refit_step: 0.99,
                },
                "scaled by 0.9138 (-0.8 dB) to pass the limits (1 steps of 0.99 after the \
                 fit, for the played codes)",
            ),
            (
                Warning::Sanity(SanityWarning::RawCounts { median: 512.3 }),
                "the median reading is 512, but psi from a skin-touch sensor is rarely above \
                 10: these look like raw ADC counts; convert them to psi before compiling",
            ),
            (
                Warning::Sanity(SanityWarning::FallsWithTouch {
                    below: 120,
                    above: 0,
                    threshold_psi: 0.08,
                    deepest: -2.0041,
                }),
                "pressure seems to fall with touch: 120 readings lie more than 0.08 below \
                 their cell's resting level (down to -2.004) against 0 above it; if the \
                 sensor's reading falls with pressure, convert it so that touch is positive \
                 psi (e.g. rest minus reading, scaled to psi)",
            ),
            (
                Warning::Sanity(SanityWarning::TouchInTareWindow {
                    cells: 1,
                    highest_psi: 1.5031,
                    tare_s: 1.0,
                    frames: 20,
                }),
                "touch in the tare window: 1 cell(s) read up to 1.503 psi above their resting \
                 level during the first 1 s (20 frames), which the leading baseline subtracts \
                 from the whole recording; if the recording begins mid-touch, try --set \
                 input.baseline=robust",
            ),
            (
                Warning::Sanity(SanityWarning::ImplausibleSpeed {
                    median_mm_s: 5080.0,
                    rate_hz: 200.0,
                    pitch_mm: 25.4,
                }),
                "the touch moves at a median 5.1 m/s at 200 Hz and 25.4 mm cells, while hands \
                 rarely exceed 1.5 m/s: if the recording's rate is lower or its cells are \
                 smaller, give them with --rate / --pitch-mm",
            ),
            (
                Warning::Sanity(SanityWarning::SingleFrameTouches {
                    touches: 4,
                    rate_hz: 20.0,
                }),
                "all 4 touches last a single frame (50 ms at 20 Hz), while taps last 50 ms and \
                 more: if the recording's rate is higher, give it with --rate",
            ),
            (
                Warning::Input(InputWarning::NanInTareWindow {
                    tare_frames: 20,
                    cells: 2,
                    readings: 30,
                    unread_cells: 1,
                    quantile: 0.02,
                }),
                "30 readings missing (NaN) in the tare window (the first 20 frames) of 2 \
                 cells: each is tared by the mean of the readings it has there, and the 1 \
                 cell with none there by its 0.02 quantile over the whole recording",
            ),
            (
                Warning::Input(InputWarning::NanInTareWindow {
                    tare_frames: 1,
                    cells: 1,
                    readings: 1,
                    unread_cells: 0,
                    quantile: 0.02,
                }),
                "1 reading missing (NaN) in the tare window (the first 1 frame) of 1 cell: \
                 each is tared by the mean of the readings it has there",
            ),
            (
                Warning::Input(InputWarning::LikelyTransposed {
                    shape: [8, 21, 100],
                    reason: TransposedBy::LastAxisLongest,
                }),
                "the array 8 x 21 x 100 is read as 8 frames of 21 x 100 cells, but its last \
                 axis (100) is far longer than the others: if it was saved as [rows, cols, \
                 frames], save it as [frames, rows, cols] (numpy: np.moveaxis(a, -1, 0))",
            ),
            (
                Warning::Input(InputWarning::LikelyTransposed {
                    shape: [8, 21, 30],
                    reason: TransposedBy::SleeveGridFirst,
                }),
                "the array 8 x 21 x 30 is read as 8 frames of 21 x 30 cells, but its first \
                 two axes are the sleeve's 8 x 21 cells: if it was saved as [rows, cols, \
                 frames], save it as [frames, rows, cols] (numpy: np.moveaxis(a, -1, 0))",
            ),
            (
                Warning::Input(InputWarning::TareErasedTouch {
                    baseline: Baseline::Robust,
                    frames: 1,
                    raw_touch_readings: 4,
                    highest_psi: 2.0,
                    cause: ErasedBy::TooShort { needed: 2 },
                }),
                "the tare removed the touch: the raw frames hold 4 touch readings up to 2.000 \
                 psi above the rest of their frame, the tared ones none, so the stimulus is \
                 silent; 1 frame is too short to tell a cell's rest from its touch: record at \
                 least 2 frames, with rest before or after the touch",
            ),
            (
                Warning::Input(InputWarning::TareErasedTouch {
                    baseline: Baseline::Leading,
                    frames: 100,
                    raw_touch_readings: 240,
                    highest_psi: 2.0049,
                    cause: ErasedBy::TouchInTareWindow,
                }),
                "the tare removed the touch: the raw frames hold 240 touch readings up to \
                 2.005 psi above the rest of their frame, the tared ones none, so the \
                 stimulus is silent; the recording begins mid-touch and the leading baseline \
                 subtracts the first seconds from all of it: use the default preset (touch) \
                 or --set input.baseline=robust",
            ),
            (
                Warning::Input(InputWarning::TareErasedTouch {
                    baseline: Baseline::Leading,
                    frames: 100,
                    raw_touch_readings: 1,
                    highest_psi: 0.5,
                    cause: ErasedBy::TouchThroughout,
                }),
                "the tare removed the touch: the raw frames hold 1 touch reading up to 0.500 \
                 psi above the rest of their frame, the tared ones none, so the stimulus is \
                 silent; the touch is held from the tare window on: use the default preset \
                 (touch) or --set input.baseline=robust, and record rest before or after the \
                 touch",
            ),
            (
                Warning::Input(InputWarning::TareErasedTouch {
                    baseline: Baseline::Robust,
                    frames: 100,
                    raw_touch_readings: 400,
                    highest_psi: 2.0049,
                    cause: ErasedBy::TouchThroughout,
                }),
                "the tare removed the touch: the raw frames hold 400 touch readings up to \
                 2.005 psi above the rest of their frame, the tared ones none, so the \
                 stimulus is silent; each touched cell is pressed for most of the recording, \
                 so its low quantile (input.baseline_quantile) is the touch: record rest \
                 before or after the touch",
            ),
        ];
        for (w, want) in cases {
            assert_eq!(describe(&w), want, "{w:?}");
        }
    }

    /// Lost touch: the share explained, then each cause with what to try, naming
    /// `--preset touch` only where that preset's tracking is off.
    #[test]
    fn low_coverage_names_each_cause_and_what_to_try() {
        let causes = vec![
            MissCause::Untracked {
                share: 0.87,
                why: UntrackedBy::TooFast {
                    speed_p90_mm_s: 54.0,
                    gate_mm_s: 5.0,
                },
            },
            MissCause::Beside {
                share: 0.1,
                radius_cells: 2.0,
            },
            MissCause::Brief {
                share: 0.03,
                min_frames: 5,
                min_ms: 250.0,
            },
        ];
        let off = Warning::LowCoverage {
            coverage: 0.0,
            threshold: 0.8,
            causes: causes.clone(),
            touch_tracking: false,
        };
        assert_eq!(
            describe(&off),
            "the tracked contacts explain 0% of the touch pressure (coverage 0.00, below \
             0.8): touch is lost; 87% of the missed touch is in frames where no contact was \
             tracked; the touch moves at up to 0.05 m/s (90th percentile), the link gate \
             follows 0.01 m/s: try --preset touch, or a wider link gate (--max-speed-mm-s); \
             10% of the missed touch lies more than 2 cells from the contact tracked in its \
             frame: a large contact (a flat hand) or a second one; try --preset touch \
             (contacts as regions); 3% of the missed touch is in touches shorter than 5 frames \
             (250 ms), the least a trajectory needs to pay its entry and exit costs: try \
             --preset touch, or lower --entry-cost and --exit-cost"
        );
        let on = Warning::LowCoverage {
            coverage: 0.764,
            threshold: 0.8,
            causes: vec![
                MissCause::Beside {
                    share: 0.93,
                    radius_cells: 2.0,
                },
                MissCause::Untracked {
                    share: 0.07,
                    why: UntrackedBy::Weak,
                },
            ],
            touch_tracking: true,
        };
        assert_eq!(
            describe(&on),
            "the tracked contacts explain 76% of the touch pressure (coverage 0.76, below \
             0.8): touch is lost; 93% of the missed touch lies more than 2 cells from the \
             contact tracked in its frame: a large contact (a flat hand) or a second one; \
             contacts are tracked whole already: try a lower footprint threshold (--set \
             track.regions.footprint_psi=0.02) or, with contact splitting, a finer lattice \
             (--set detect.split.spacing_cells=1); 7% of the missed touch is in frames where no \
             contact was tracked; its detections are too weak to start a trajectory: try \
             lower --entry-cost and --exit-cost"
        );
        let dropouts = Warning::LowCoverage {
            coverage: 0.5,
            threshold: 0.8,
            causes: vec![MissCause::Untracked {
                share: 1.0,
                why: UntrackedBy::Dropouts { count: 3 },
            }],
            touch_tracking: false,
        };
        assert_eq!(
            describe(&dropouts),
            "the tracked contacts explain 50% of the touch pressure (coverage 0.50, below \
             0.8): touch is lost; 100% of the missed touch is in frames where no contact was \
             tracked; the touch drops out for one or two frames 3 times (flicker) and the \
             pieces are too short to track: try --preset touch (links across missing frames)"
        );
    }
}
