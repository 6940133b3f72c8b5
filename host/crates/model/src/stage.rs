//! The pipeline's timed steps, named once: `touchc_pipeline::compile` times each one and
//! reports the wall seconds under [`Stage::name`], so a step renamed here is renamed in
//! every report and in every reader of one that looks it up by [`Stage`].

/// How a stretch of time since the last lap is shared out: each stage with its share
/// (the shares add up to 1).
pub type Shares = [(Stage, f64)];

/// One timed step of a compile, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stage {
    /// Stage 0: load checks, tare and trim, the active-scene crop.
    Tare,
    /// Stage 1: upsample and blur.
    Preprocess,
    /// Stage 2: local maxima and their costs.
    Detect,
    /// Stage 3: linking detections into trajectories.
    Track,
    /// How much of the touch the trajectories explain (not a pipeline stage, but timed).
    Coverage,
    /// Stage 4: the placement search.
    Placement,
    /// Stage 5: per-actuator pressure signals.
    Signals,
    /// Stage 6: conditioning to currents and the safety-limit check.
    Condition,
    /// Stage 7: keyframes and the stimulus file.
    Keyframes,
    /// The whole compile, wall clock from start to end.
    Total,
}

impl Stage {
    /// Every stage, in pipeline order, `Total` last.
    pub const ALL: [Stage; 10] = [
        Stage::Tare,
        Stage::Preprocess,
        Stage::Detect,
        Stage::Track,
        Stage::Coverage,
        Stage::Placement,
        Stage::Signals,
        Stage::Condition,
        Stage::Keyframes,
        Stage::Total,
    ];

    /// The key of this stage in a report's `seconds` (`touchc compile --report`).
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Tare => "tare",
            Stage::Preprocess => "preprocess",
            Stage::Detect => "detect",
            Stage::Track => "track",
            Stage::Coverage => "coverage",
            Stage::Placement => "placement",
            Stage::Signals => "signals",
            Stage::Condition => "condition",
            Stage::Keyframes => "keyframes",
            Stage::Total => "total",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_distinct_and_in_pipeline_order() {
        let names: Vec<_> = Stage::ALL.iter().map(|s| s.name()).collect();
        let mut unique = names.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        assert!(Stage::ALL.windows(2).all(|w| w[0] < w[1]));
    }
}
