//! The whole compile, with the default config and layout, on small recordings built
//! from the bytes (`touchc_testkit::fuzz_input`: up to 100 frames of up to 6 x 6
//! cells, values from 0 to 255 steps of 1e-8 to 1e7 psi, 0xff = NaN). Compiling returns
//! a stimulus or an error and never panics; a stimulus decodes and plays to its end.
#![no_main]

use libfuzzer_sys::fuzz_target;
use touch_protocol::{DeviceConfig, Player, Stimulus};
use touchc_pipeline::compile::{compile, CompileOptions};
use touchc_input::recording::Recording;
use touchc_testkit::fuzz_input;

fuzz_target!(|data: &[u8]| {
    let Some(array) = fuzz_input::recording(data) else {
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
