//! The whole compile, with the default config and layout, on small recordings built
//! from the bytes: up to 100 frames of up to 6 x 6 cells (the default tare needs 41),
//! values from 0 to 255 steps of 1e-8 to 1e7 psi, 0xff = NaN. Compiling returns a
//! stimulus or an error and never panics; a stimulus decodes and plays to its end.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ndarray::Array3;
use touch_protocol::{DeviceConfig, Player, Stimulus};
use touchc::compile::{compile, CompileOptions};
use touchc::input::recording::Recording;

fuzz_target!(|data: &[u8]| {
    let [t, r, c, scale, cells @ ..] = data else {
        return;
    };
    let dim = (
        1 + usize::from(*t) % 100,
        1 + usize::from(*r) % 6,
        1 + usize::from(*c) % 6,
    );
    let step = 10f64.powi(i32::from(*scale % 16) - 8);
    let n = dim.0 * dim.1 * dim.2;
    let values = (0..n)
        .map(|i| match cells.get(i) {
            Some(0xff) => f64::NAN,
            Some(&b) => f64::from(b) * step,
            None => 0.0,
        })
        .collect();
    let Ok(array) = Array3::from_shape_vec(dim, values) else {
        return;
    };
    let Ok(rec) = Recording::from_array("fuzz", array.view()) else {
        return;
    };
    let Ok(compiled) = compile(&rec, &CompileOptions::default()) else {
        return;
    };
    let stimulus = Stimulus::decode(&compiled.stimulus).expect("a compiled stimulus decodes");
    let mut player = Player::new(&stimulus, &DeviceConfig::default());
    let bound = u64::from(stimulus.header().playback_ms()) + 1 + 2_000;
    let mut ticks = 0u64;
    while !player.is_done() {
        player.tick();
        ticks += 1;
        assert!(ticks <= bound, "the player did not finish");
    }
});
