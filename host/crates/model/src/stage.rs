//! The pipeline's timed steps, named once: `touchc_pipeline::compile` times each one into
//! a [`StageSeconds`], read by [`Stage`], and a report file keys each under
//! [`Stage::name`], so a step renamed here is renamed in every report.

use serde::ser::{Serialize, SerializeMap, Serializer};

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

/// Wall seconds per [`Stage`] of one compile; a stage that did not run has none
/// (a recording without touch is not tracked or placed).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StageSeconds([Option<f64>; Stage::ALL.len()]);

impl StageSeconds {
    /// The seconds of `stage`, if it ran.
    pub fn get(&self, stage: Stage) -> Option<f64> {
        self.0[stage as usize]
    }

    /// The whole compile's seconds ([`Stage::Total`]); 0 before it is known.
    pub fn total(&self) -> f64 {
        self.get(Stage::Total).unwrap_or(0.0)
    }

    /// Adds `seconds` to `stage` (which then has run).
    pub fn add(&mut self, stage: Stage, seconds: f64) {
        let s = &mut self.0[stage as usize];
        *s = Some(s.unwrap_or(0.0) + seconds);
    }

    /// Every stage that ran with its seconds, in pipeline order, [`Stage::Total`] last.
    pub fn iter(&self) -> impl Iterator<Item = (Stage, f64)> + '_ {
        Stage::ALL
            .iter()
            .filter_map(|&stage| self.get(stage).map(|s| (stage, s)))
    }
}

/// A map from [`Stage::name`] to seconds, the stages that ran only, keys in
/// alphabetical order (the order a report file has always listed them in).
impl Serialize for StageSeconds {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut named: Vec<(&str, f64)> = self.iter().map(|(st, v)| (st.name(), v)).collect();
        named.sort_by_key(|&(name, _)| name);
        let mut map = s.serialize_map(Some(named.len()))?;
        for (name, v) in named {
            map.serialize_entry(name, &v)?;
        }
        map.end()
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
        // `StageSeconds` indexes by the discriminant: `ALL` must list them in order.
        assert!(Stage::ALL.iter().enumerate().all(|(i, &s)| s as usize == i));
    }

    #[test]
    fn seconds_are_read_by_stage_and_written_by_name() {
        let mut s = StageSeconds::default();
        assert_eq!((s.get(Stage::Tare), s.total()), (None, 0.0));
        s.add(Stage::Tare, 0.25);
        s.add(Stage::Track, 0.5);
        s.add(Stage::Tare, 0.25);
        s.add(Stage::Total, 2.0);
        assert_eq!(s.get(Stage::Tare), Some(0.5));
        assert_eq!(s.get(Stage::Placement), None);
        assert_eq!(s.total(), 2.0);
        let order: Vec<Stage> = s.iter().map(|(st, _)| st).collect();
        assert_eq!(order, [Stage::Tare, Stage::Track, Stage::Total]);
        assert_eq!(
            serde_json::to_string(&s).unwrap(),
            r#"{"tare":0.5,"total":2.0,"track":0.5}"#
        );
    }
}
