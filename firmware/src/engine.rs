//! The 1 kHz tick: write the frame computed last tick, feed the watchdog, then
//! handle the buttons and compute the next frame.
//!
//! Writing first makes the output update jitter-free: it happens at a fixed point
//! after the timer interrupt, whatever the player's code path costs. The one
//! exception is a slot a `Play` command starts: its first frame is written in the
//! tick that starts it, once computed, so that a command that lands just as a
//! tick begins still plays within 2 ms (the carrier's own period, 49 us, already
//! moves a frame's effect by more than the tick takes to compute it). No allocation,
//! no blocking, no logging: what to log goes out through a callback (a lock-free
//! queue in the firmware).

use touch_protocol::OutputSink;

use crate::button::{Buttons, Event};
use crate::control::{Controller, Report};
use crate::output::{Frame, IDLE_FRAME};

/// The independent watchdog, fed once per tick.
pub trait Watchdog {
    /// Restarts the watchdog's countdown.
    fn feed(&mut self);
}

/// The tick's state: outputs, watchdog, buttons and the playback controller.
pub struct Engine<'a, S, W, const N: usize> {
    sink: S,
    watchdog: W,
    next: Frame,
    buttons: Buttons<N>,
    controller: Controller<'a>,
}

impl<'a, S: OutputSink, W: Watchdog, const N: usize> Engine<'a, S, W, N> {
    /// The first tick writes 0 A on every channel.
    pub fn new(sink: S, watchdog: W, buttons: Buttons<N>, controller: Controller<'a>) -> Self {
        Engine {
            sink,
            watchdog,
            next: IDLE_FRAME,
            buttons,
            controller,
        }
    }

    /// One tick. `edges` holds each button's newest EXTI edge since the last tick.
    /// The frame computed in the last tick is written and the watchdog fed first;
    /// then `written` is called (the firmware lowers the tick's priority there, below
    /// the link's interrupts, so that they wait for the write alone and not for the
    /// next frame's computation, a keyframe's decoding among it). When a command
    /// started a slot in this tick, its first frame is written once computed.
    pub fn tick(
        &mut self,
        edges: [Option<bool>; N],
        mut log: impl FnMut(Report),
        written: impl FnOnce(),
    ) {
        self.sink.write(&self.next);
        self.watchdog.feed();
        written();
        self.controller.send_later(&mut log);
        for event in self.buttons.tick(edges) {
            if let Some(report) = self.controller.handle(event) {
                log(report);
            }
        }
        let sink = &mut self.sink;
        self.next = self
            .controller
            .tick_with(&mut log, |first| sink.write(first));
    }

    /// Applies an event as if a button had produced it (for tests and a debugger).
    pub fn inject(&mut self, event: Event) -> Option<Report> {
        self.controller.handle(event)
    }

    /// The playback controller.
    pub fn controller(&self) -> &Controller<'a> {
        &self.controller
    }

    /// The output sink.
    pub fn sink(&self) -> &S {
        &self.sink
    }

    /// The output sink, for a model that keeps its record between ticks.
    pub fn sink_mut(&mut self) -> &mut S {
        &mut self.sink
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::button::{Mode, DEBOUNCE_TICKS};
    use crate::output::device_config;
    use crate::testutil::{bank, constant_stimulus};
    use touch_protocol::Bank;

    #[derive(Default)]
    struct Recorder(std::vec::Vec<Frame>);
    impl OutputSink for Recorder {
        fn write(&mut self, codes: &Frame) {
            self.0.push(*codes);
        }
    }
    #[derive(Default)]
    struct CountingDog(u32);
    impl Watchdog for CountingDog {
        fn feed(&mut self) {
            self.0 += 1;
        }
    }

    /// Runs `ticks` ticks with edges at given ticks; returns the tick of each report.
    fn drive<const N: usize>(
        e: &mut Engine<'_, Recorder, CountingDog, N>,
        ticks: usize,
        edges: &[(usize, usize, bool)],
    ) -> std::vec::Vec<(usize, Report)> {
        let mut reports = std::vec::Vec::new();
        for t in 0..ticks {
            let mut now = [None; N];
            for &(at, button, level) in edges {
                if at == t {
                    now[button] = Some(level);
                }
            }
            e.tick(now, |r| reports.push((t, r)), || {});
        }
        reports
    }

    /// An engine on the bank `image`, recording every frame it writes.
    fn engine<const N: usize>(image: &[u8], mode: Mode) -> Engine<'_, Recorder, CountingDog, N> {
        let bank = Bank::decode(image).unwrap();
        let ctrl = Controller::new(bank, device_config());
        Engine::new(
            Recorder::default(),
            CountingDog::default(),
            Buttons::new(mode),
            ctrl,
        )
    }

    fn first_active(frames: &[Frame]) -> usize {
        frames
            .iter()
            .position(|f| *f != IDLE_FRAME)
            .expect("something played")
    }

    #[test]
    fn one_button_latency_is_one_tick_after_debouncing() {
        let image = bank(&[constant_stimulus("a", 300, 400)]);
        let mut e = engine::<1>(&image, Mode::PlayNext);
        // First press right at power-up (tick 0), released 80 ms later.
        let reports = drive(&mut e, 300, &[(0, 0, true), (80, 0, false)]);
        let (started, r) = reports[0];
        assert_eq!(r, Report::Started(0));
        assert_eq!(
            started,
            80 + usize::from(DEBOUNCE_TICKS) - 1,
            "debounced on release"
        );
        let latency = first_active(&e.sink().0) - started;
        assert_eq!(
            latency, 1,
            "first non-idle frame one tick after the debounced edge"
        );
        assert_eq!(e.watchdog.0, 300);
        assert_eq!(e.sink().0[0], IDLE_FRAME);
    }

    #[test]
    fn per_slot_latency_is_one_tick_after_debouncing() {
        let image = bank(&[
            constant_stimulus("a", 300, 400),
            constant_stimulus("b", 500, 400),
        ]);
        let mut e = engine::<2>(&image, Mode::PerSlot);
        let reports = drive(&mut e, 100, &[(10, 1, true), (60, 1, false)]);
        assert_eq!(
            reports[0],
            (10 + usize::from(DEBOUNCE_TICKS) - 1, Report::Started(1))
        );
        assert_eq!(first_active(&e.sink().0) - reports[0].0, 1);
    }

    #[test]
    fn plays_to_the_end_and_rests_at_zero() {
        let image = bank(&[constant_stimulus("a", 300, 400)]);
        let mut e = engine::<1>(&image, Mode::PlayNext);
        assert_eq!(e.inject(Event::Toggle), Some(Report::Started(0)));
        let reports = drive(&mut e, 1000, &[]);
        assert!(matches!(reports.last(), Some((_, Report::Finished(0)))));
        assert_eq!(*e.sink().0.last().unwrap(), IDLE_FRAME);
        assert_eq!(e.controller().playing(), None);
    }

    mod invariants {
        use super::*;
        use crate::testutil::stimulus_from;
        use proptest::prelude::*;
        use touch_protocol::{Limits, CHANNELS, IDLE_CODE};

        /// 50 mA/ms at 1000 mA full scale is 102.4 codes: the slew limit holds on
        /// the codes after rounding, so 102 (49.8 mA) at most.
        const MAX_STEP: u16 = 102;

        fn any_stimulus() -> impl Strategy<Value = Vec<u8>> {
            (
                10u16..=100,
                proptest::collection::vec(proptest::array::uniform8(any::<i16>()), 1..20),
                (1u16..=3000, 1u16..=200, 1u16..=2000, 1u32..=50_000_000),
            )
                .prop_map(
                    |(
                        period,
                        frames,
                        (peak_ma, slew_ma_per_ms, continuous_ma, i2t_budget_ma2s),
                    )| {
                        let limits = Limits {
                            peak_ma,
                            slew_ma_per_ms,
                            continuous_ma,
                            i2t_budget_ma2s,
                        };
                        stimulus_from("p", period, &frames, limits)
                    },
                )
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(48))]

            /// Whatever the stimuli and however the buttons are pressed: no output
            /// ever steps faster than the hard slew limit (starts, stops, switches and
            /// faults included), and once the presses stop everything rests at 0 A.
            #[test]
            fn never_steps_and_always_comes_to_rest(
                stimuli in proptest::collection::vec(any_stimulus(), 1..4),
                presses in proptest::collection::vec((0usize..2500, 0usize..4, 5usize..900), 0..8),
            ) {
                let image = bank(&stimuli);
                let mut e = engine::<4>(&image, Mode::PerSlot);
                let mut edges = std::vec::Vec::new();
                for &(at, button, held) in &presses {
                    edges.push((at, button, true));
                    edges.push((at + held, button, false));
                }
                // Longest stimulus: 19 keyframes * 100 ms, plus ramps.
                drive(&mut e, 3500 + 2100, &edges);
                let frames = &e.sink().0;
                let mut prev = [IDLE_CODE; CHANNELS];
                for (t, f) in frames.iter().enumerate() {
                    for c in 0..CHANNELS {
                        prop_assert!(f[c].abs_diff(prev[c]) <= MAX_STEP, "tick {} channel {}: {} -> {}", t, c, prev[c], f[c]);
                    }
                    prev = *f;
                }
                prop_assert_eq!(*frames.last().unwrap(), IDLE_FRAME);
                prop_assert_eq!(e.controller().playing(), None);
            }
        }
    }
}
