//! How each gesture moves and presses: its contacts, drawn from the seeded generator.

use super::contacts::{Contact, Frame, Lobe, Profile, Rng, RUB_HZ};
use super::{Gesture, Tuning};

/// Contacts of one gesture starting at `t0` seconds; returns them and the gesture length.
///
/// The random draws of the shipped gestures come first and in their original order, so
/// that an untuned gesture on the sleeve is the same as ever.
pub(super) fn gesture(
    kind: Gesture,
    t0: f64,
    rng: &mut Rng,
    tuning: &Tuning,
    fr: Frame,
) -> (Vec<Contact>, f64) {
    let mut contacts = Vec::new();
    let length = match kind {
        Gesture::Stroke => stroke(&mut contacts, t0, rng, tuning, fr),
        Gesture::Tap => tap(&mut contacts, t0, rng, tuning, fr),
        Gesture::Pat => pat(&mut contacts, t0, rng, fr),
        Gesture::Squeeze => squeeze(&mut contacts, t0, rng, fr),
        Gesture::Shake => shake(&mut contacts, t0, rng, tuning, fr),
        Gesture::Palm => palm(&mut contacts, t0, rng, fr),
        Gesture::Hand => hand(&mut contacts, t0, rng, tuning, fr),
        Gesture::Rub => rub(&mut contacts, t0, rng, tuning, fr),
        Gesture::Strokes => strokes(&mut contacts, t0, rng, tuning, fr),
        Gesture::Rest => 2.0,
        Gesture::Tickle => tickle(&mut contacts, t0, rng, fr),
        Gesture::Scratch => scratch(&mut contacts, t0, rng, fr),
    };
    (contacts, length)
}

/// A Gaussian contact that rises and falls over its whole length, without a lobe or
/// wavering: the shipped gestures' fingertips and pats.
fn blob(
    gesture: Gesture,
    start: f64,
    length: f64,
    peak_psi: f64,
    sigma: (f64, f64),
    path: Box<dyn Fn(f64) -> (f64, f64)>,
) -> Contact {
    Contact {
        gesture,
        start,
        length,
        peak_psi,
        sigma,
        profile: Profile::Gaussian,
        ramp_s: None,
        path,
        lobe: None,
        waver: None,
    }
}

/// One fingertip sliding along the arm, at `stroke_speed_mps` when it is given.
fn stroke(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let (sx, sy) = (fr.sx, fr.sy);
    let row = rng.range(2.5, 5.5);
    let (from, to) = (rng.range(1.5, 3.5), rng.range(15.5, 18.0));
    let drift = rng.range(-1.0, 1.0);
    let mut length = rng.range(1.0, 1.4);
    let mut ramp_s = None;
    if let Some(v) = tuning.stroke_speed_mps {
        length = fr.travel_s((to - from) * sx, v);
        ramp_s = Some((0.05f64).min(length / 4.0));
    }
    let mut c = blob(
        Gesture::Stroke,
        t0,
        length,
        rng.range(1.0, 1.3),
        (0.9, 0.8),
        Box::new(move |u| (sx * (from + (to - from) * u), sy * (row + drift * u))),
    );
    c.ramp_s = ramp_s;
    contacts.push(c);
    length
}

/// Three fingertip presses at one spot, `tap_s` long when it is given (then each
/// centred near a frame time).
fn tap(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let (sx, sy) = (fr.sx, fr.sy);
    let (x, y) = (rng.range(4.0, 16.0), rng.range(2.5, 5.5));
    let (tap, every) = match tuning.tap_s {
        None => (0.2, 0.4),
        Some(s) => (s, (s + 0.3).max(0.4)),
    };
    for k in 0..3 {
        let mut start = t0 + every * k as f64;
        let mut ramp_s = None;
        if tuning.tap_s.is_some() {
            // A brief tap still shows in a frame: its middle falls within a
            // quarter frame of a frame time, inside the plateau.
            let ramp = (tap / 5.0).min(0.01);
            let period = 1.0 / fr.rate_hz;
            let frame = (start * fr.rate_hz).ceil() / fr.rate_hz;
            let jitter = rng.range(-0.25, 0.25) * period.min(tap - 2.0 * ramp);
            start = frame - tap / 2.0 + jitter;
            ramp_s = Some(ramp);
        }
        let mut c = blob(
            Gesture::Tap,
            start,
            tap,
            rng.range(0.9, 1.4),
            (0.7, 0.7),
            Box::new(move |_| (sx * x, sy * y)),
        );
        c.ramp_s = ramp_s;
        contacts.push(c);
    }
    every * 2.0 + tap + 0.2
}

/// Four flat-hand pats at neighbouring spots along the arm.
fn pat(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, fr: Frame) -> f64 {
    let (sx, sy) = (fr.sx, fr.sy);
    let mut x = rng.range(3.0, 7.0);
    for k in 0..4 {
        let y = rng.range(3.0, 5.0);
        let here = x;
        contacts.push(blob(
            Gesture::Pat,
            t0 + 0.5 * k as f64,
            0.3,
            rng.range(0.6, 1.0),
            (1.6, 1.4),
            Box::new(move |_| (sx * here, sy * y)),
        ));
        x += rng.range(2.5, 4.0);
    }
    2.0
}

/// A grip: four fingertips in a line along one side of the forearm and the heel of the
/// hand on the other, rising, held and released together.
fn squeeze(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, fr: Frame) -> f64 {
    let (sx, sy) = (fr.sx, fr.sy);
    let x = rng.range(5.0, 9.0);
    let peak = rng.range(0.7, 1.0);
    for k in 0..4 {
        let (fx, fy) = (
            x + 2.2 * k as f64 + rng.range(-0.3, 0.3),
            rng.range(1.6, 2.4),
        );
        contacts.push(blob(
            Gesture::Squeeze,
            t0,
            1.8,
            peak * rng.range(0.85, 1.0),
            (0.8, 0.8),
            Box::new(move |_| (sx * fx, sy * fy)),
        ));
    }
    let (px, py) = (x + 3.3, rng.range(5.6, 6.4));
    contacts.push(blob(
        Gesture::Squeeze,
        t0,
        1.8,
        peak * 0.8,
        (2.0, 1.0),
        Box::new(move |_| (sx * px, sy * py)),
    ));
    1.8
}

/// A contact moving back and forth across the arm: the shipped 3 Hz shake, or one
/// at `shake_hz` and `shake_amplitude_mm`.
fn shake(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let (sx, sy) = (fr.sx, fr.sy);
    let x = rng.range(6.0, 15.0);
    let c = match (tuning.shake_hz, tuning.shake_amplitude_mm) {
        (None, None) => blob(
            Gesture::Shake,
            t0,
            1.5,
            rng.range(0.8, 1.2),
            (1.0, 1.0),
            Box::new(move |u| {
                (
                    sx * x,
                    sy * (4.0 + 2.0 * (2.0 * std::f64::consts::PI * 3.0 * 1.5 * u).sin()),
                )
            }),
        ),
        (hz, amp) => {
            let hz = hz.unwrap_or(3.0);
            let amp = amp.unwrap_or(2.0 * fr.pitch_mm) / fr.pitch_mm;
            let cy = fr.rows / 2.0;
            // A fingertip the size of a stroke's.
            let mut c = blob(
                Gesture::Shake,
                t0,
                1.5,
                rng.range(0.8, 1.2),
                (0.9, 0.8),
                Box::new(move |u| {
                    let phase = 2.0 * std::f64::consts::PI * hz * 1.5 * u;
                    (sx * x, cy + amp * phase.sin())
                }),
            );
            c.ramp_s = Some(0.15);
            c
        }
    };
    contacts.push(c);
    1.5
}

/// A flat hand pressed and held in the middle of the sensor.
fn palm(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, fr: Frame) -> f64 {
    let (x, y) = (fr.cols / 2.0 + rng.range(-1.5, 1.5), fr.rows / 2.0);
    contacts.push(Contact {
        gesture: Gesture::Palm,
        start: t0,
        length: 1.5,
        peak_psi: rng.range(0.4, 0.7),
        sigma: (3.0, 2.0),
        profile: Profile::Flat,
        ramp_s: Some(0.15),
        path: Box::new(move |_| (x, y)),
        lobe: None,
        waver: None,
    });
    1.5
}

/// A flat hand held for `hold_s`: the flat, strong part (palm and fingers) with the heel
/// of the hand beside it towards the wrist, broad and about a third as strong, well above
/// the touch threshold but below half the peak, and a shoulder of the palm rather than a
/// peak of its own (the pressure falls all the way from the palm).
fn hand(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let hold = tuning.hold_s.unwrap_or(3.0);
    let (x, y) = (
        fr.cols / 2.0 + 1.0 + rng.range(-0.5, 0.5),
        fr.rows / 2.0 + rng.range(-0.5, 0.5),
    );
    contacts.push(Contact {
        gesture: Gesture::Hand,
        start: t0,
        length: hold,
        peak_psi: rng.range(0.6, 0.9),
        sigma: (1.8, 2.2),
        profile: Profile::Flat,
        ramp_s: Some(0.2),
        path: Box::new(move |_| (x, y)),
        lobe: Some(Lobe {
            offset: (-2.8, 0.0),
            sigma: (1.5, 1.8),
            share: rng.range(0.3, 0.4),
        }),
        waver: None,
    });
    hold
}

/// A flat hand sliding back and forth along the arm at [`RUB_HZ`]: its speed peaks at
/// `stroke_speed_mps` in the middle of each sweep and falls to nothing at each turn, as
/// a rubbing palm does.
fn rub(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let v = tuning.stroke_speed_mps.unwrap_or(0.45);
    let hold = tuning.hold_s.unwrap_or(3.0);
    let hz = RUB_HZ;
    let amp = v * 1000.0 / (2.0 * std::f64::consts::PI * hz) / fr.pitch_mm;
    let (x, y) = (
        fr.cols / 2.0 + rng.range(-0.5, 0.5),
        fr.rows / 2.0 + rng.range(-0.5, 0.5),
    );
    let phase0 = rng.range(0.0, std::f64::consts::TAU);
    contacts.push(Contact {
        gesture: Gesture::Rub,
        start: t0,
        length: hold,
        peak_psi: rng.range(0.5, 0.8),
        sigma: (1.6, 1.8),
        profile: Profile::Flat,
        ramp_s: Some(0.2),
        path: Box::new(move |u| {
            let phase = std::f64::consts::TAU * hz * hold * u + phase0;
            (x + amp * (phase.sin() - phase0.sin()), y)
        }),
        lobe: None,
        waver: None,
    });
    hold
}

/// `strokes` strokes back and forth along the arm, `gap_s` (or up to `gap_max_s`)
/// apart.
fn strokes(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, tuning: &Tuning, fr: Frame) -> f64 {
    let v = tuning.stroke_speed_mps.unwrap_or(0.3);
    let gap = tuning.gap_s.unwrap_or(0.15);
    let count = tuning.strokes.unwrap_or(3);
    let row = fr.rows / 2.0 + rng.range(-1.0, 1.0);
    let (a, b) = (fr.cols * 0.15, fr.cols * 0.85);
    let each = fr.travel_s(b - a, v);
    // With a longest gap, each gap is drawn between the two, and each stroke
    // changes speed along its way (half to one and a half times `v`) and
    // presses lightly, its pressure wavering (real strokes: a median peak of
    // about a quarter psi).
    let varied = tuning.gap_max_s.map(|max| max.max(gap));
    let mut t = t0;
    for k in 0..count {
        let (from, to) = if k % 2 == 0 { (a, b) } else { (b, a) };
        let ease = if varied.is_some() { 0.5 } else { 0.0 };
        let peak = match varied {
            Some(_) => rng.range(0.2, 0.4),
            None => rng.range(0.8, 1.2),
        };
        let mut c = blob(
            Gesture::Strokes,
            t,
            each,
            peak,
            (0.9, 0.8),
            Box::new(move |u| {
                // Monotone for ease < 1: the stroke never turns back.
                let s = u + ease * (std::f64::consts::TAU * u).sin() / std::f64::consts::TAU;
                (from + (to - from) * s, row)
            }),
        );
        c.ramp_s = Some((0.04f64).min(each / 4.0));
        if varied.is_some() {
            c.waver = Some((0.5, rng.range(2.0, 4.0)));
        }
        contacts.push(c);
        t += each;
        if k + 1 < count {
            t += match varied {
                Some(max) => rng.range(gap, max),
                None => gap,
            };
        }
    }
    t - t0
}

/// A light fingertip wandering over a few cells: three sines of 0.7-2.3 Hz in each
/// direction (at most about 0.3 m/s), pressing 0.15-0.35 psi and dipping by two thirds
/// 3-5 times a second.
fn tickle(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, fr: Frame) -> f64 {
    let length = 3.0;
    let (x, y) = (
        fr.cols / 2.0 + rng.range(-1.0, 1.0),
        fr.rows / 2.0 + rng.range(-0.5, 0.5),
    );
    let waves: Vec<(f64, f64, f64, f64)> = (0..3)
        .map(|_| {
            (
                rng.range(0.7, 2.3),
                rng.range(0.0, std::f64::consts::TAU),
                rng.range(0.0, std::f64::consts::TAU),
                rng.range(0.3, 0.6),
            )
        })
        .collect();
    let mut c = blob(
        Gesture::Tickle,
        t0,
        length,
        rng.range(0.15, 0.35),
        (0.8, 0.8),
        Box::new(move |u| {
            let t = u * length;
            let (mut dx, mut dy) = (0.0, 0.0);
            for &(hz, px, py, a) in &waves {
                let w = std::f64::consts::TAU * hz * t;
                dx += a * (w + px).sin();
                dy += 0.6 * a * (w + py).cos();
            }
            (x + dx, y + dy)
        }),
    );
    c.ramp_s = Some(0.1);
    c.waver = Some((0.65, rng.range(3.0, 5.0)));
    contacts.push(c);
    length
}

/// Fingernails scratching: a contact narrow along the arm and long across it, back and
/// forth over 2.5 cells either side at 4 Hz (1.6 m/s mid-sweep), for 3 s.
fn scratch(contacts: &mut Vec<Contact>, t0: f64, rng: &mut Rng, fr: Frame) -> f64 {
    let (length, hz, amp) = (3.0, 4.0, 2.5);
    let (x, y) = (
        fr.cols / 2.0 + rng.range(-0.5, 0.5),
        fr.rows / 2.0 + rng.range(-0.5, 0.5),
    );
    let phase0 = rng.range(0.0, std::f64::consts::TAU);
    let mut c = blob(
        Gesture::Scratch,
        t0,
        length,
        rng.range(0.4, 0.8),
        (0.5, 1.3),
        Box::new(move |u| {
            let phase = std::f64::consts::TAU * hz * length * u + phase0;
            (x + amp * (phase.sin() - phase0.sin()), y)
        }),
    );
    c.ramp_s = Some(0.1);
    contacts.push(c);
    length
}
