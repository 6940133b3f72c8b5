//! Decoded stimuli played back to back on one device, with one persistent thermal
//! state, as the firmware does: presses (starts and stops) at fuzzer-chosen ticks,
//! idle ticks between plays. Asserts, on the output codes, that no step exceeds the
//! slew limit, no code the peak, and that the coils' heat, measured independently from
//! the codes, never passes the budget.
#![no_main]

use libfuzzer_sys::fuzz_target;
use touch_protocol::player::{code_to_amps, DeviceConfig, Player};
use touch_protocol::{Limits, Stimulus, Thermal, CHANNELS, IDLE_CODE};

/// Ticks one input may run, so that each execution stays short.
const MAX_TICKS: usize = 200_000;

/// A small device budget, so that the fuzzer reaches thermal trips quickly.
const DEVICE: DeviceConfig = DeviceConfig {
    full_scale_ma: 1000,
    limits: Limits {
        peak_ma: 1000,
        slew_ma_per_ms: 50,
        continuous_ma: 600,
        i2t_budget_ma2s: 500_000,
    },
};


/// The heat as a thermometer on the outputs would see it, A^2 s per channel.
struct Meter {
    heat: [f64; CHANNELS],
    prev: [u16; CHANNELS],
}

impl Meter {
    fn frame(&mut self, codes: &[u16; CHANNELS], limits: &Limits) {
        let full = DEVICE.full_scale_ma;
        // The coil's own rating: the device's (a stimulus may only claim less).
        let cont = f64::from(DEVICE.limits.continuous_ma) / 1000.0;
        let budget = f64::from(limits.i2t_budget_ma2s) / 1e6;
        let slew = f64::from(limits.slew_ma_per_ms) / 1000.0;
        let peak = f64::from(limits.peak_ma) / 1000.0;
        for c in 0..CHANNELS {
            let a = code_to_amps(codes[c], full);
            let step = (a - code_to_amps(self.prev[c], full)).abs();
            assert!(step <= slew + 1e-9, "channel {c}: step {step} A > {slew} A");
            assert!(a.abs() <= peak + 0.0005, "channel {c}: {a} A > {peak} A");
            self.heat[c] = (self.heat[c] + (a * a - cont * cont) / 1000.0).max(0.0);
            assert!(self.heat[c] <= budget + 1e-9, "channel {c}: {} A^2 s > {budget}", self.heat[c]);
        }
        self.prev = *codes;
    }
}

fuzz_target!(|data: &[u8]| {
    // First byte: how many schedule bytes follow; then the schedule (pairs of
    // (idle ticks / 16, play ticks / 16)); the rest is a stimulus payload.
    let Some((&n, rest)) = data.split_first() else { return };
    let n = usize::from(n % 32) * 2;
    if rest.len() < n {
        return;
    }
    let (schedule, payload) = rest.split_at(n);
    let file = touch_protocol::container::seal(
        touch_protocol::stimulus::MAGIC,
        touch_protocol::stimulus::VERSION,
        payload,
    )
        .expect("fuzz inputs are small");
    let Ok(s) = Stimulus::decode(&file) else { return };
    // The device's own limits are the stricter: those are what the coil can take.
    let limits = s.limits().min(DEVICE.limits);
    let mut meter = Meter { heat: [0.0; CHANNELS], prev: [IDLE_CODE; CHANNELS] };
    let mut thermal = Thermal::COLD;
    let mut ticks = 0;
    for pair in schedule.chunks(2).cycle().take(64) {
        let (idle, play) = (usize::from(pair[0]) * 16, usize::from(pair[1]) * 64 + 1);
        for _ in 0..idle {
            thermal.idle_tick(&DEVICE.limits);
            meter.frame(&[IDLE_CODE; CHANNELS], &limits);
        }
        if thermal.check_start(&limits).is_ok() {
            let mut p = Player::with_thermal(&s, &DEVICE, thermal);
            let mut played = 0;
            while !p.is_done() {
                if played == play {
                    p.stop();
                }
                let t = p.tick();
                meter.frame(&t.codes, &limits);
                played += 1;
                assert!(played <= play + 70_000, "no rest after a stop");
            }
            thermal = p.thermal();
            ticks += played;
        }
        ticks += idle;
        if ticks > MAX_TICKS || schedule.is_empty() {
            break;
        }
    }
});
