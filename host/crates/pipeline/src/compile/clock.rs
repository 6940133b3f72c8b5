//! Stage timings of one compile.

use std::time::Instant;

use touchc_model::stage::{Shares, Stage, StageSeconds};

/// The seconds each stage took, by laps.
pub(super) struct Clock {
    seconds: StageSeconds,
    start: Instant,
    lap: Instant,
}

impl Clock {
    pub(super) fn new() -> Self {
        let now = Instant::now();
        Clock {
            seconds: StageSeconds::default(),
            start: now,
            lap: now,
        }
    }

    pub(super) fn stage(&mut self, stage: Stage) {
        self.split(&[(stage, 1.0)]);
    }

    /// The time since the last lap, shared out among `shares` (stage, share).
    pub(super) fn split(&mut self, shares: &Shares) {
        let now = Instant::now();
        let elapsed = (now - self.lap).as_secs_f64();
        for &(stage, share) in shares {
            self.seconds.add(stage, share * elapsed);
        }
        self.lap = now;
    }

    pub(super) fn finish(mut self) -> StageSeconds {
        self.seconds
            .add(Stage::Total, self.start.elapsed().as_secs_f64());
        self.seconds
    }
}
