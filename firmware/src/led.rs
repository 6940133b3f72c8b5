//! The status LED: what a person reads off the board, as timed patterns.
//!
//! Three kinds of light a person tells apart without a watch: a short blink (200 ms,
//! counted), a long light (1 s or more) and a flicker (50 ms, too fast to count).
//! Every pattern is built from them so that no two read alike:
//!
//! | LED | meaning |
//! |---|---|
//! | off | ready, nothing playing |
//! | on, steady | a slot plays (or ramps down to 0 A) |
//! | `n + 1` short blinks, once | slot `n` is selected (at power-up: slot 0, one blink; then after each long press) |
//! | flicker for 2 s, once | start refused: a coil is still too hot |
//! | long, short, long, once | start refused: the slot was compiled for another layout |
//! | long, then `k` short blinks, a pause, forever | the bank is refused (`k`: [`BootError::blinks`]) |
//!
//! [`Led`] holds the pattern shown and when it began; [`Led::at`] says the level at any
//! millisecond and when it next changes, so the firmware's LED task sleeps until then
//! (or until a report) and the host tests read the same timeline.

use crate::boot::BootError;
use crate::control::{Report, StreamReport};

/// A short blink, ms on and off: slow enough to count.
pub const BLINK_ON_MS: u32 = 200;
/// The gap between short blinks, ms.
pub const BLINK_OFF_MS: u32 = 300;
/// A long light, ms.
pub const LONG_MS: u32 = 1200;
/// A flicker's half period, ms: too fast to count, unlike a blink.
pub const FLICKER_MS: u32 = 50;
/// The pause that ends a repeating pattern's cycle, ms.
pub const PAUSE_MS: u32 = 2000;

/// A pattern the LED shows over the steady level (on while playing, else off).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Slot `n` is selected: `n + 1` short blinks, once.
    Selected(u8),
    /// A start refused because a coil is too hot: a flicker for 2 s, once.
    TooHot,
    /// A start refused because the slot is for another layout: long, short, long, once.
    BadSlot,
    /// The bank is refused: a long light, then `k` short blinks and a pause, forever.
    BadBank(u8),
}

/// The flicker's length, in flashes (2 s).
const FLICKERS: usize = 20;

impl Pattern {
    /// Segment `i` of one cycle: (on, ms), or `None` past the end of the cycle.
    fn segment(self, i: usize) -> Option<(bool, u32)> {
        let blink = |j: usize| {
            let on = j.is_multiple_of(2);
            (on, if on { BLINK_ON_MS } else { BLINK_OFF_MS })
        };
        match self {
            Pattern::Selected(n) => (i < 2 * (usize::from(n) + 1)).then(|| blink(i)),
            Pattern::TooHot => (i < 2 * FLICKERS).then_some((i.is_multiple_of(2), FLICKER_MS)),
            Pattern::BadSlot => [
                (true, LONG_MS),
                (false, BLINK_OFF_MS),
                (true, BLINK_ON_MS),
                (false, BLINK_OFF_MS),
                (true, LONG_MS),
                (false, BLINK_OFF_MS),
            ]
            .get(i)
            .copied(),
            Pattern::BadBank(k) => {
                let blinks = 2 * usize::from(k);
                match i {
                    0 => Some((true, LONG_MS)),
                    1 => Some((false, BLINK_OFF_MS * 2)),
                    i if i < 2 + blinks => Some(blink(i - 2)),
                    i if i == 2 + blinks => Some((false, PAUSE_MS)),
                    _ => None,
                }
            }
        }
    }

    /// Whether the pattern repeats until the next boot.
    fn repeats(self) -> bool {
        matches!(self, Pattern::BadBank(_))
    }

    /// The length of one cycle, ms.
    fn cycle_ms(self) -> u64 {
        (0..)
            .map_while(|i| self.segment(i))
            .map(|(_, ms)| u64::from(ms))
            .sum()
    }
}

/// The LED's level at a moment, and until when it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Light {
    /// On or off.
    pub on: bool,
    /// The millisecond it may change at, or `None`: it holds until the next report.
    pub until_ms: Option<u64>,
}

/// What the LED shows: a pattern since some millisecond over the steady level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Led {
    shown: Option<(Pattern, u64)>,
    playing: bool,
}

impl Default for Led {
    fn default() -> Self {
        Self::new()
    }
}

impl Led {
    /// Off, nothing shown.
    pub const fn new() -> Self {
        Led {
            shown: None,
            playing: false,
        }
    }

    /// The refused bank's code, from `now_ms` on, forever.
    pub fn refused(e: BootError, now_ms: u64) -> Self {
        Led {
            shown: Some((Pattern::BadBank(e.blinks()), now_ms)),
            playing: false,
        }
    }

    /// Shows `pattern` from `now_ms`, in place of any pattern still showing.
    pub fn show(&mut self, pattern: Pattern, now_ms: u64) {
        self.shown = Some((pattern, now_ms));
    }

    /// Takes in what the controller reported at `now_ms`.
    pub fn report(&mut self, report: &Report, now_ms: u64) {
        match *report {
            Report::Started(_) => {
                // The steady light says it plays at once, whatever was blinking.
                self.playing = true;
                self.shown = None;
            }
            Report::Finished(_) => self.playing = false,
            Report::Selected(slot) => {
                // A bank holds at most 32 slots.
                let slot = u8::try_from(slot).unwrap_or(u8::MAX);
                self.show(Pattern::Selected(slot), now_ms);
            }
            Report::TooHot(..) => self.show(Pattern::TooHot, now_ms),
            Report::BadSlot(..) => self.show(Pattern::BadSlot, now_ms),
            Report::Stopping(_) | Report::Fault(..) => {}
            // The host's stream lights the LED as a slot does, and its refusal on a hot
            // coil shows as the button's would.
            Report::Stream(StreamReport::Started) => {
                self.playing = true;
                self.shown = None;
            }
            Report::Stream(StreamReport::Finished) => self.playing = false,
            Report::Stream(StreamReport::TooHot(_)) => self.show(Pattern::TooHot, now_ms),
            Report::Stream(StreamReport::Stopping(_) | StreamReport::Fault(_)) => {}
        }
    }

    /// The level at `now_ms` (not before the pattern's start) and until when it holds.
    pub fn at(&self, now_ms: u64) -> Light {
        let steady = Light {
            on: self.playing,
            until_ms: None,
        };
        let Some((pattern, start)) = self.shown else {
            return steady;
        };
        let mut elapsed = now_ms.saturating_sub(start);
        let cycle = pattern.cycle_ms();
        let mut cycle_start = start;
        if pattern.repeats() && cycle > 0 {
            let cycles = elapsed / cycle;
            cycle_start += cycles * cycle;
            elapsed -= cycles * cycle;
        }
        let mut begin = 0u64;
        for i in 0.. {
            let Some((on, ms)) = pattern.segment(i) else {
                break;
            };
            let end = begin + u64::from(ms);
            if elapsed < end {
                return Light {
                    on,
                    until_ms: Some(cycle_start + end),
                };
            }
            begin = end;
        }
        steady
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boot::check_bank;
    use crate::testutil::{bank, constant_stimulus, for_layout};
    use std::string::String;
    use std::vec::Vec;
    use touch_protocol::thermal::TooHot;
    use touch_protocol::Error;

    /// The LED's level every millisecond over `ms`, from `led` as `reports` (at their
    /// millisecond) change it.
    fn timeline(mut led: Led, from: u64, ms: u64, reports: &[(u64, Report)]) -> Vec<bool> {
        (from..from + ms)
            .map(|t| {
                for (at, r) in reports {
                    if *at == t {
                        led.report(r, t);
                    }
                }
                led.at(t).on
            })
            .collect()
    }

    /// What a person watching reads: each light as `.` (short, counted), `-` (long)
    /// or `~` (a flicker), a gap of 1.5 s or more as `|`, a light still on at the end
    /// after 3 s or more as `*` (any other light or gap the window cuts is not read).
    /// Panics on a light or gap no one could class (too near two kinds).
    fn read(levels: &[bool]) -> String {
        let mut out = String::new();
        let mut runs = Vec::new();
        for &on in levels {
            match runs.last_mut() {
                Some((level, n)) if *level == on => *n += 1,
                _ => runs.push((on, 1u32)),
            }
        }
        let last = runs.len().saturating_sub(1);
        for (i, &(on, ms)) in runs.iter().enumerate() {
            match (on, ms) {
                (true, 3000..) if i == last => out.push('*'),
                _ if i == last => {}
                (true, 1..=80) => out.push('~'),
                (true, 150..=300) => out.push('.'),
                (true, 900..=2500) => out.push('-'),
                (false, 1..=700) => {}
                (false, 1500..) => out.push('|'),
                _ => panic!("a light or gap of {ms} ms ({on}) reads as no kind: {runs:?}"),
            }
        }
        out
    }

    fn refused_bank_reads(image: &[u8]) -> (BootError, String) {
        let mut region = std::vec![0xFF; 4096];
        region[..image.len()].copy_from_slice(image);
        let e = check_bank(&region).unwrap_err();
        (e, read(&timeline(Led::refused(e, 5000), 5000, 30_000, &[])))
    }

    /// Boots banks refused for each reason and reads their LED codes: a long light,
    /// then the reason's count of short blinks, a pause, again and again.
    #[test]
    fn a_refused_bank_shows_a_long_light_then_its_count_of_blinks_forever() {
        let good = bank(&[constant_stimulus("a", 200, 100)]);

        // 4: a CRC mismatch (one bit flipped in the stimulus).
        let mut corrupt = good.clone();
        corrupt[good.len() - 6] ^= 1;
        let (e, seen) = refused_bank_reads(&corrupt);
        assert!(matches!(e, BootError::Corrupt(_)), "{e:?}");
        assert!(seen.starts_with("-....|-....|-....|"), "{seen}");

        // 5: the bank's CRCs hold, but its stimulus is malformed (7 channels).
        let mut bad = good.clone();
        let at = good.len() - constant_stimulus("a", 200, 100).len() - 4;
        bad[at + 10] = 7;
        let n = bad.len();
        let crc = touch_protocol::container::crc32(&bad[at..n - 8]);
        bad[n - 8..n - 4].copy_from_slice(&crc.to_le_bytes());
        let crc = touch_protocol::container::crc32(&bad[..n - 4]);
        bad[n - 4..].copy_from_slice(&crc.to_le_bytes());
        let (e, seen) = refused_bank_reads(&bad);
        assert!(matches!(e, BootError::Invalid(_)), "{e:?}");
        assert!(seen.starts_with("-.....|-.....|-.....|"), "{seen}");

        // 3: not a bank.
        let mut not_bank = good.clone();
        not_bank[0] = b'X';
        let (e, seen) = refused_bank_reads(&not_bank);
        assert!(matches!(e, BootError::NotABank(_)), "{e:?}");
        assert!(seen.starts_with("-...|-...|"), "{seen}");

        // 6: a bank compiled for another layout geometry.
        let one = constant_stimulus("mirrored", 200, 100);
        let other = bank(&[for_layout(&one, crate::output::LAYOUT_HASH ^ 1)]);
        let (e, seen) = refused_bank_reads(&other);
        assert!(matches!(e, BootError::OtherLayout(_)), "{e:?}");
        assert!(seen.starts_with("-......|-......|"), "{seen}");

        // 2: a bank with no slot is its own code; the erased region plays the
        // built-in bank instead and shows no code at all.
        let seen = read(&timeline(Led::refused(BootError::Empty, 0), 0, 12_000, &[]));
        assert!(seen.starts_with("-..|-..|"), "{seen}");
    }

    /// Everything a person may see reads differently: the selection of each slot, the
    /// refusals, the bank codes, the steady light of a playback.
    #[test]
    fn every_pattern_reads_differently() {
        let hot = TooHot {
            channel: 2,
            permille: 900,
            cooldown_ms: 1000,
        };
        let layout = Error::WrongLayout {
            found: 1,
            expected: 2,
        };
        let mut seen: Vec<(String, String)> = Vec::new();
        let mut note = |what: String, reports: &[(u64, Report)], led: Led| {
            let r = read(&timeline(led, 0, 12_000, reports));
            assert!(!r.is_empty(), "{what}: nothing to see");
            for (other, r2) in &seen {
                assert_ne!(&r, r2, "{what} reads as {other}: {r}");
            }
            seen.push((what, r));
        };
        for slot in 0..6 {
            note(
                std::format!("slot {slot} selected"),
                &[(0, Report::Selected(slot))],
                Led::new(),
            );
        }
        note("too hot".into(), &[(0, Report::TooHot(0, hot))], Led::new());
        note(
            "another layout".into(),
            &[(0, Report::BadSlot(1, layout))],
            Led::new(),
        );
        for e in [
            BootError::Empty,
            BootError::NotABank(Error::BadMagic {
                found: [0; 4],
                expected: [0; 4],
            }),
            BootError::Corrupt(Error::BadLength(0)),
            BootError::Invalid(Error::KeyframeOutOfRange),
            BootError::OtherLayout(Error::WrongLayout {
                found: 1,
                expected: 2,
            }),
        ] {
            note(std::format!("bank refused: {e:?}"), &[], Led::refused(e, 0));
        }
        note("playing".into(), &[(0, Report::Started(0))], Led::new());
        let blinks: Vec<&str> = seen.iter().map(|(_, r)| r.as_str()).collect();
        assert_eq!(&blinks[..3], [".", "..", "..."]);
        assert_eq!(blinks[6], "~".repeat(FLICKERS));
        assert_eq!(blinks[7], "-.-");
        assert_eq!(blinks[13], "*");
    }

    /// Pressing play lights the LED at once, even in the middle of a selection's
    /// blinks; it goes off when the slot is back at 0 A, and a selection made while
    /// the slot ramps down still blinks whole.
    #[test]
    fn the_light_follows_the_playback_and_a_selection_blinks_over_it() {
        let levels = timeline(
            Led::new(),
            0,
            6000,
            &[
                (0, Report::Selected(3)),
                (700, Report::Started(3)),
                (2000, Report::Selected(4)),
                (2100, Report::Finished(3)),
            ],
        );
        // Blinks from 0, cut at 700 ms by the playback's steady light.
        assert!(levels[..200].iter().all(|&on| on));
        assert!(levels[200..500].iter().all(|&on| !on));
        assert!(levels[700..2000].iter().all(|&on| on));
        // From 2 s, slot 4's five blinks whole, then off.
        assert_eq!(read(&levels[2000..]), ".....");
        assert!(!levels[5999]);
    }

    /// A host's stream lights the LED while it plays, as a slot does; its start
    /// refused on a hot coil shows the hot-coil flicker.
    #[test]
    fn a_stream_lights_the_led_while_it_plays() {
        let hot = touch_protocol::thermal::TooHot {
            channel: 0,
            permille: 990,
            cooldown_ms: 1000,
        };
        let levels = timeline(
            Led::new(),
            0,
            4000,
            &[
                (100, Report::Stream(StreamReport::Started)),
                (1000, Report::Stream(StreamReport::Finished)),
                (2000, Report::Stream(StreamReport::TooHot(hot))),
            ],
        );
        assert!(levels[..100].iter().all(|&on| !on));
        assert!(levels[100..1000].iter().all(|&on| on));
        assert!(levels[1000..2000].iter().all(|&on| !on));
        let mut alone = Led::new();
        alone.show(Pattern::TooHot, 2000);
        assert!(levels[2000..] == timeline(alone, 2000, 2000, &[])[..]);
        assert!(levels[2000..].iter().any(|&on| on));
    }
}
