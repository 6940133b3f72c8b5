//! Writes a labelled synthetic data set for `touchc select`: class folders of `.npy`
//! recordings and a `manifest.csv` with each recording's person.
//!
//! `cargo run --release -p touchc-select --example labelled_set -- DIR [PER_CLASS]
//! [FRAMES] [CLASSES] [PEOPLE] [realistic|separable|gestures]`; the benchmark's set is
//! `DIR 117 705 6 10` (702 recordings of 705 x 8 x 21 frames, realistic); `gestures`
//! is seven touch gestures on the 10 x 10 grid at 54 Hz (`DIR 119 540 7 10 gestures`).

use touchc_select::synthetic::{labelled_set, write, Mix, SetSpec};
use touchc_synth::Sensor;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args.first().ok_or(
        "usage: labelled_set DIR [PER_CLASS] [FRAMES] [CLASSES] [PEOPLE] [realistic|separable|gestures]",
    )?;
    let num = |i: usize, default: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let frames = num(2, 0)?;
    let mix = match args.get(5).map_or("realistic", String::as_str) {
        "realistic" => Mix::Realistic,
        "separable" => Mix::Separable,
        "gestures" => Mix::Gestures,
        other => {
            return Err(format!("unknown mix {other}: realistic, separable or gestures").into())
        }
    };
    let spec = SetSpec {
        per_class: num(1, 20)?,
        frames: (frames > 0).then_some(frames),
        classes: num(3, 6)?,
        people: num(4, 10)?,
        sensor: match mix {
            Mix::Gestures => Sensor::Grid10,
            Mix::Realistic | Mix::Separable => Sensor::Sleeve,
        },
        mix,
        seed: 1,
    };
    let set = labelled_set(&spec);
    write(std::path::Path::new(dir), &set)?;
    println!("{dir}: {} recordings", set.len());
    Ok(())
}
