//! Any text as a config file and as a layout file: parsing and validation returns a value or an error and never panics; what parses writes back
//! to text that parses to the same value. The text also goes through the config's layers
//! (`touchc --config`, `--set`) as the command line lays them: as a file over each
//! preset, and each of its lines as a `SECTION.KEY=VALUE` assignment.
#![no_main]

use libfuzzer_sys::fuzz_target;
use touchc_model::config::{Config, Layers, Preset};
use touchc_model::layout::Layout;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(cfg) = toml::from_str::<Config>(text) {
        // Compared as text: a NaN knob is not equal to itself.
        let once = toml::to_string(&cfg).expect("a parsed config serialises");
        let again: Config = toml::from_str(&once).expect("a written config parses");
        assert_eq!(toml::to_string(&again).expect("serialises"), once);
        // Validation names the knob it refuses and never panics, on any value.
        if let Err(e) = cfg.validated() {
            assert!(!e.to_string().is_empty());
        }
    }
    for preset in Preset::ALL {
        // What the layers build is valid, and a layer in error is named.
        match Layers::new(preset).file("fuzz.toml", text).build() {
            Ok(valid) => assert!(valid.validate().is_ok()),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
        match Layers::new(preset).sets(text.lines()).build() {
            Ok(valid) => assert!(valid.validate().is_ok()),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
    match Layout::from_toml_str(text, "fuzz.toml") {
        Ok(layout) => {
            let _ = layout.circles();
            let once = layout.to_toml_string().expect("a valid layout serialises");
            let again = Layout::from_toml_str(&once, "again").expect("a written layout parses");
            assert_eq!(again, layout);
        }
        Err(e) => assert!(e.to_string().contains("fuzz.toml"), "{e}"),
    }
});
