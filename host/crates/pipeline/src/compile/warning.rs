//! What a compile noticed that its user should know, as values: each [`Warning`] holds
//! the figures behind it, and a front end words it (the command line's sentences, with
//! the flags to try, live there).

use crate::coverage::MissCause;
use crate::rendered::Shortfall;
use touchc_input::sanity::SanityWarning;
use touchc_input::warning::InputWarning;

/// Something about a compile that succeeded that the user should know: touch lost,
/// a budget or limit reached, the signal scaled, or a recording that looks wrong.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// The input stage's notes on the recording's shape and tare (the report also
    /// lists these on their own, [`super::Report::input_warnings`]).
    Input(InputWarning),
    /// The recording probably does not mean what the compile assumes (units, sign,
    /// rate or pitch).
    Sanity(SanityWarning),
    /// Too few readings above the touch threshold: the stimulus is silent.
    NoTouch {
        /// Readings above the threshold after the tare.
        readings: usize,
        /// The touch threshold, psi (`input.touch_threshold_psi`).
        threshold_psi: f64,
        /// The most readings that still count as no touch (`input.min_touch_readings`).
        min_readings: usize,
    },
    /// The tracked contacts explain less of the touch pressure than
    /// [`super::COVERAGE_WARNING`].
    LowCoverage {
        /// The share explained, 0 to 1.
        coverage: f64,
        /// The share below which this is a warning.
        threshold: f64,
        /// The likely causes of the rest, largest first.
        causes: Vec<MissCause>,
        /// The `touch` preset's tracking (links across missing frames, contacts as
        /// regions or split on a lattice) was on, so it is not what to try.
        touch_tracking: bool,
    },
    /// The flow used every unit of `track.max_trajectories`: further contacts are not
    /// tracked.
    TrajectoryLimit {
        /// Trajectories tracked.
        trajectories: usize,
        /// `track.max_trajectories`.
        max_trajectories: usize,
        /// The coverage, 0 to 1 (how much touch the ones tracked explain).
        coverage: f64,
    },
    /// The min-cost flow stopped at its work budget: weaker contacts may be untracked.
    FlowBudget {
        /// Edges the flow scanned.
        flow_work: u64,
        /// The budget's work per edge of the flow's graph.
        work_per_edge: u64,
        /// Trajectories tracked before it stopped.
        trajectories: usize,
        /// The coverage, 0 to 1.
        coverage: f64,
    },
    /// No trajectory was tracked: every actuator stays at rest.
    NoTrajectory,
    /// The trajectory-subset search ran out of its node budget on some transforms,
    /// which kept the best subset found.
    SubsetBudget {
        /// Nodes per transform.
        node_budget: u64,
        /// Transforms whose search ran out.
        transforms_inexact: usize,
        /// Transforms searched.
        transforms_evaluated: usize,
        /// Trajectories in the scene.
        trajectories: usize,
    },
    /// No trajectory passes through an actuator's workspace: the stimulus is silent.
    OutsideWorkspaces,
    /// The sleeve plays much less of the touch than the tracker follows: the rendered
    /// coverage is under [`crate::rendered::SHORTFALL_SHARE`] of the tracking coverage.
    Shortfall(Shortfall),
    /// The signal was scaled down to pass the safety limits (`fit`).
    Fitted {
        /// The scale applied, below 1.
        scale: f64,
        /// Further steps after the fit, for the played codes.
        refits: u32,
        /// The factor of each such step.
        refit_step: f64,
    },
}
