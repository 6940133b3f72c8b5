//! `touchc plot` to PNG of a long stimulus: every trace stays inside its own panel,
//! between its peak-limit lines, as in the SVG and in `render --csv`.

use crate::bin::{command, ok, s, touchc};
use crate::stimuli::stimulus;
use touchc::viz::plot::{LIMIT, TRACE};

/// `seconds` s of keyframes every 40 ms: every channel rests at 0 A and, once a
/// second after the first (each channel at its own phase), jumps to +0.7 A for one keyframe and to
/// -0.6 A for one more: narrow spikes up and down, as a compiled touch has, whose
/// min/max reduction makes a long plot's trace turn back on itself.
fn spiky(seconds: usize) -> Vec<u8> {
    let keyframes: Vec<[f64; 8]> = (0..seconds * 25)
        .map(|k| {
            // The first second at rest: the player's 10 ms ramp starts from 0 A.
            std::array::from_fn(|ch| match (k >= 25, (k + 3 * ch) % 25) {
                (true, 10) => 0.7,
                (true, 12) => -0.6,
                _ => 0.0,
            })
        })
        .collect();
    stimulus("spiky", &keyframes)
}

fn decode(path: &std::path::Path) -> (usize, usize, Vec<[u8; 3]>) {
    let file = std::fs::File::open(path).unwrap();
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = buf[..info.buffer_size()]
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width as usize, info.height as usize, pixels)
}

/// Each panel's box between its peak-limit lines: `(x0, x1, y_top, y_bottom)`. The
/// panels are four columns of two rows: in each quarter of the width, the rows with
/// many limit-coloured pixels are the four lines, top and bottom of each panel.
fn limit_boxes(w: usize, h: usize, px: &[[u8; 3]]) -> Vec<(usize, usize, usize, usize)> {
    let red = [LIMIT.0, LIMIT.1, LIMIT.2];
    let mut boxes = Vec::new();
    for quarter in 0..4 {
        let xs = quarter * w / 4..(quarter + 1) * w / 4;
        // (y, first x, last x) of each line, a line being a row of > 100 red pixels.
        let lines: Vec<(usize, usize, usize)> = (0..h)
            .filter_map(|y| {
                let reds: Vec<usize> = xs.clone().filter(|&x| px[y * w + x] == red).collect();
                (reds.len() > 100).then(|| (y, reds[0], reds[reds.len() - 1] + 1))
            })
            .collect();
        assert_eq!(lines.len(), 4, "quarter {quarter}: {lines:?}");
        for pair in lines.chunks(2) {
            let (x0, x1) = (pair[0].1.min(pair[1].1), pair[0].2.max(pair[1].2));
            boxes.push((x0, x1, pair[0].0, pair[1].0));
        }
    }
    boxes
}

/// Six minutes of spikes to PNG: no trace pixel lies outside every panel's box
/// between its limit lines (the traces stay within +-0.7 A of a +-1 A limit), and
/// each of the eight panels holds its trace.
#[test]
fn a_long_stimulus_plots_to_png_within_its_panels() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("long.touch");
    std::fs::write(&file, spiky(360)).unwrap();
    let png = dir.path().join("long.png");
    ok(&touchc(&["plot", s(&file), "-o", s(&png)]));
    let (w, h, px) = decode(&png);
    let boxes = limit_boxes(w, h, &px);
    assert_eq!(boxes.len(), 8, "{boxes:?}");
    // The trace is 2 px wide: it may touch a limit line, not pass it.
    let slack = 2;
    let inside = |x: usize, y: usize| {
        boxes.iter().any(|&(x0, x1, top, bottom)| {
            (x0.saturating_sub(slack)..x1 + slack).contains(&x)
                && (top.saturating_sub(slack)..=bottom + slack).contains(&y)
        })
    };
    let blue = [TRACE.0, TRACE.1, TRACE.2];
    let outside: Vec<(usize, usize)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| px[y * w + x] == blue && !inside(x, y))
        .collect();
    assert!(
        outside.is_empty(),
        "{} trace pixels outside the panels, e.g. {:?}",
        outside.len(),
        &outside[..outside.len().min(10)]
    );
    for &(x0, x1, top, bottom) in &boxes {
        let traced = (top..=bottom)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| px[y * w + x] == blue)
            .count();
        assert!(traced > 500, "panel at x {x0}..{x1}: {traced} trace pixels");
    }
}

/// The PNG's text is set in the bundled font, not found through the system's
/// fontconfig: with fontconfig pointed at an empty directory (a machine without fonts)
/// the picture is the same, byte for byte, and its title strip holds text.
#[test]
fn a_png_plot_draws_its_text_without_system_fonts() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("short.touch");
    std::fs::write(&file, spiky(3)).unwrap();
    let usual = dir.path().join("usual.png");
    ok(&touchc(&["plot", s(&file), "-o", s(&usual)]));

    let empty = dir.path().join("no-fonts");
    std::fs::create_dir(&empty).unwrap();
    let conf = empty.join("fonts.conf");
    std::fs::write(
        &conf,
        format!(
            "<?xml version=\"1.0\"?>\n<fontconfig><dir>{}</dir><cachedir>{}</cachedir></fontconfig>\n",
            empty.display(),
            empty.join("cache").display()
        ),
    )
    .unwrap();
    let bare = dir.path().join("bare.png");
    ok(&command()
        .args(["plot", s(&file), "-o", s(&bare)])
        .env("FONTCONFIG_FILE", &conf)
        .env("FONTCONFIG_PATH", &empty)
        .env("XDG_DATA_HOME", &empty)
        .output()
        .unwrap());
    assert_eq!(
        std::fs::read(&usual).unwrap(),
        std::fs::read(&bare).unwrap(),
        "the PNG differs without system fonts"
    );

    // The title sits above the panels' top limit lines: dark ink there is its text.
    let (w, h, px) = decode(&bare);
    let top = limit_boxes(w, h, &px).iter().map(|b| b.2).min().unwrap();
    let ink = px[..top * w]
        .iter()
        .filter(|p| p.iter().all(|&c| c < 96))
        .count();
    assert!(
        ink > 200,
        "{ink} dark pixels above the panels: no title text"
    );
}
