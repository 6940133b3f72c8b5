//! Drives the real `touchc` binary: `plot` (PNG, SVG, bank slots) and `render --wav`.

use crate::bin;

use bin::{ok, refused, touchc};
use std::path::{Path, PathBuf};
use touchc_model::trajectory::Columns;

use touch_protocol::bank;

use crate::stimuli;

/// A 1 s stimulus: channel `active` swells to +0.95 A, channel `silent` stays at 0 A,
/// the others hold the -0.9 A pre-dent.
fn stimulus_bytes(name: &str, active: usize, silent: usize) -> Vec<u8> {
    let swell: stimuli::Shape = |x| 0.95 * (std::f64::consts::PI * x).sin().powi(2);
    let keyframes = stimuli::one_second(-0.9, &[(active, swell), (silent, |_| 0.0)]);
    stimuli::stimulus(name, &keyframes)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Decodes a PNG into (width, height, RGB bytes).
fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// Per panel of the 2 x 4 grid, the trace-coloured pixels above and below the 0 A line,
/// found halfway between the panel's two peak-limit lines (a 3 px band around it counts
/// as neither). `title` = height of the title band above the panels.
fn trace_pixels(w: u32, h: u32, rgb: &[u8], title: u32) -> [[usize; 2]; 8] {
    use touchc::viz::plot::{LIMIT, TRACE};
    let px = |x: u32, y: u32| {
        let i = 3 * (y * w + x) as usize;
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    let (pw, ph) = (w / 4, (h - title) / 2);
    let mut counts = [[0; 2]; 8];
    for (ch, count) in counts.iter_mut().enumerate() {
        let (x0, y0) = (pw * (ch as u32 % 4), title + ph * (ch as u32 / 4));
        let red: Vec<u32> = (y0..y0 + ph)
            .filter(|&y| {
                (x0..x0 + pw)
                    .filter(|&x| px(x, y) == [LIMIT.0, LIMIT.1, LIMIT.2])
                    .count()
                    > 20
            })
            .collect();
        let (top, bottom) = (red[0], red[red.len() - 1]);
        assert!(bottom > top + 50, "ch{ch}: limit lines at {red:?}");
        let zero = (top + bottom) / 2;
        for y in y0..y0 + ph {
            for x in x0..x0 + pw {
                if px(x, y) == [TRACE.0, TRACE.1, TRACE.2] {
                    if y + 3 < zero {
                        count[0] += 1;
                    } else if y > zero + 3 {
                        count[1] += 1;
                    }
                }
            }
        }
    }
    counts
}

#[test]
fn plot_png_lays_channels_out_like_the_sleeve() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "a.touch", &stimulus_bytes("a", 6, 1));
    let png = dir.path().join("a.png");
    ok(&touchc(&[
        "plot",
        file.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--width",
        "1000",
        "--height",
        "600",
    ]));
    let (w, h, rgb) = decode_png(&png);
    assert_eq!((w, h), (1000, 600));
    let counts = trace_pixels(w, h, &rgb, 30);
    // Channel 6 = row 1, column 2: bottom row, third panel; its swell is above 0 A.
    assert!(counts[6][0] > 100, "{counts:?}");
    // Channel 1 is silent: nothing off its 0 A line.
    assert_eq!(counts[1], [0, 0], "{counts:?}");
    for ch in [0, 2, 3, 4, 5, 7] {
        assert!(counts[ch][1] > 100, "ch{ch}: {counts:?}");
        assert!(counts[ch][0] < counts[ch][1] / 4, "ch{ch}: {counts:?}");
    }
}

#[test]
fn plot_reads_a_bank_slot_and_writes_svg() {
    let dir = tempfile::tempdir().unwrap();
    let a = stimulus_bytes("first", 0, 7);
    let b = stimulus_bytes("second", 7, 0);
    let image = bank::encode(&[&a, &b]).unwrap();
    let file = write(dir.path(), "sleeve.bank", &image);
    let svg_path = dir.path().join("slot1.svg");
    ok(&touchc(&[
        "plot",
        file.to_str().unwrap(),
        "--slot",
        "1",
        "-o",
        svg_path.to_str().unwrap(),
    ]));
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert!(svg.starts_with("<svg"));
    assert!(svg.contains("second: 1.011 s"), "title names slot 1");
    assert!(svg.contains("peak limit \u{b1}1.00 A"));
    for ch in 0..8 {
        let elbow = if ch % 4 == 0 { " (elbow)" } else { "" };
        let caption = format!("ch{ch}: row {}, column {}{elbow}\n", ch / 4, ch % 4);
        assert!(svg.contains(&caption), "{caption}");
    }
    // Two limit lines and one trace per panel, in their colours.
    assert_eq!(svg.matches("stroke=\"#D62728\"").count(), 16);
    assert_eq!(svg.matches("stroke=\"#1F77B4\"").count(), 8);

    // A missing slot and an unknown extension are errors naming the file.
    let out = touchc(&["plot", file.to_str().unwrap(), "--slot", "5", "-o", "x.svg"]);
    assert!(refused(&out).contains("sleeve.bank"));
    let out = touchc(&["plot", file.to_str().unwrap(), "-o", "x.jpg"]);
    assert!(refused(&out).contains("x.jpg"));
    // Too small to lay out eight panels: refused, and nothing written.
    let tiny = dir.path().join("tiny.png");
    let out = touchc(&[
        "plot",
        file.to_str().unwrap(),
        "-o",
        tiny.to_str().unwrap(),
        "--width",
        "10",
    ]);
    assert_eq!(out.status.code(), Some(2), "a usage error");
    let err = refused(&out);
    assert!(
        err.contains("--width 10") && err.contains("320 to 8000 px"),
        "{err}"
    );
    assert!(!tiny.exists());
}

#[test]
fn render_wav_is_the_players_output_at_the_chosen_rate() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "a.touch", &stimulus_bytes("a", 2, 5));
    let wav_path = dir.path().join("a.wav");
    let csv_path = dir.path().join("a.csv");
    ok(&touchc(&[
        "render",
        file.to_str().unwrap(),
        "--wav",
        wav_path.to_str().unwrap(),
        "--rate",
        "8000",
        "--csv",
        "-o",
        csv_path.to_str().unwrap(),
    ]));
    let wav = std::fs::read(&wav_path).unwrap();
    // 1011 ticks (1001 signal + 10 ramp down) span 1.010 s: 8081 frames at 8 kHz.
    let frames = 1010 * 8 + 1;
    assert_eq!(wav.len(), 68 + frames * 16);
    assert_eq!(&wav[..4], b"RIFF");
    assert_eq!(&wav[8..16], b"WAVEfmt ");
    assert_eq!(u16::from_le_bytes([wav[20], wav[21]]), 0xFFFE);
    assert_eq!(u16::from_le_bytes([wav[22], wav[23]]), 8);
    assert_eq!(u32::from_le_bytes(wav[24..28].try_into().unwrap()), 8000);
    assert_eq!(&wav[60..64], b"data");
    assert_eq!(
        u32::from_le_bytes(wav[64..68].try_into().unwrap()) as usize,
        frames * 16
    );
    let sample = |frame: usize, ch: usize| {
        let i = 68 + frame * 16 + ch * 2;
        f64::from(i16::from_le_bytes([wav[i], wav[i + 1]])) / 32768.0
    };
    // The WAV agrees with the CSV (amperes, 1 A full scale) at every tick.
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    for (t, line) in csv.lines().skip(1).enumerate() {
        let amps: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        for ch in 0..8 {
            let s = sample(t * 8, ch);
            assert!((s - amps[ch + 1]).abs() < 1e-4, "t {t} ch{ch}: {s}");
        }
    }
    // Mid-signal: channel 2 near +0.95 A, channel 5 silent, the others pre-dented.
    assert!((sample(4000, 2) - 0.95).abs() < 0.01, "{}", sample(4000, 2));
    assert_eq!(sample(4000, 5), 0.0);
    assert!((sample(4000, 0) + 0.9).abs() < 0.01);

    // Rates outside 1 kHz ..= 768 kHz are refused, naming the output.
    let out = touchc(&[
        "render",
        file.to_str().unwrap(),
        "--wav",
        wav_path.to_str().unwrap(),
        "--rate",
        "500",
    ]);
    assert!(refused(&out).contains("a.wav"));
}

/// Decodes a GIF into the full RGBA pictures a viewer shows: each frame's rectangle laid
/// over the picture before it (transparent pixels keep what was there); returns
/// (width, height, pictures, delays).
fn decode_gif(path: &Path) -> (u16, u16, Vec<Vec<u8>>, Vec<u16>) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut decoder = opts.read_info(file).unwrap();
    let (w, h) = (decoder.width(), decoder.height());
    let (mut frames, mut delays) = (Vec::new(), Vec::new());
    let mut canvas = vec![0u8; 4 * usize::from(w) * usize::from(h)];
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        if frames.is_empty() {
            assert_eq!(
                (frame.width, frame.height, frame.left, frame.top),
                (w, h, 0, 0),
                "the first frame is whole"
            );
        }
        assert_ne!(frame.dispose, gif::DisposalMethod::Background);
        let (fw, left, top) = (
            usize::from(frame.width),
            usize::from(frame.left),
            usize::from(frame.top),
        );
        assert!(left + fw <= usize::from(w));
        assert!(top + usize::from(frame.height) <= usize::from(h));
        for (i, px) in frame.buffer.chunks_exact(4).enumerate() {
            if px[3] != 0 {
                let at = 4 * ((top + i / fw) * usize::from(w) + left + i % fw);
                canvas[at..at + 4].copy_from_slice(px);
            }
        }
        frames.push(canvas.clone());
        delays.push(frame.delay);
    }
    (w, h, frames, delays)
}

#[test]
fn preview_animates_every_frame_with_the_trajectories() {
    use touchc::viz::preview;
    use touchc_input::recording::Recording;
    use touchc_pipeline::compile::{compile, CompileOptions};

    let dir = tempfile::tempdir().unwrap();
    let rec_path = dir.path().join("stroke.npy");
    ok(&touchc(&[
        "synth",
        "stroke",
        "--seed",
        "4",
        "-o",
        rec_path.to_str().unwrap(),
    ]));
    let gif_path = dir.path().join("stroke.gif");
    ok(&touchc(&[
        "preview",
        rec_path.to_str().unwrap(),
        "-o",
        gif_path.to_str().unwrap(),
    ]));
    let (w, h, frames, delays) = decode_gif(&gif_path);

    // The same compile the command runs, to know where things must be.
    let rec = Recording::load(&rec_path).unwrap();
    let opts = CompileOptions {
        fit: true,
        crop: false,
        keep_scene: true,
        ..CompileOptions::default()
    };
    let compiled = compile(&rec, &opts).unwrap();
    let layout = preview::layout(&compiled).unwrap();
    let tare = touchc_model::config::Sampling::PAPER.frames(opts.config.input.trim_s);
    assert_eq!(
        frames.len(),
        rec.dim().0 - 2 * tare,
        "one GIF frame per frame"
    );
    assert_eq!((u32::from(w), u32::from(h)), (layout.width, layout.height));
    assert!(delays.iter().all(|&d| d == 5), "20 Hz = 5 cs per frame");

    // The first selected trajectory: its dot is drawn in the first trajectory colour at
    // each of its frames, and the pixels there change as it moves on.
    let placement = compiled.placement.as_ref().unwrap();
    let traj = &compiled.tracked.as_ref().unwrap().trajectories[placement.selected[0]];
    assert!(traj.len() > 10, "a stroke is tracked over many frames");
    let colour = preview::TRAJECTORY_COLOURS[0];
    let near = |frame: &[u8], (cx, cy): (i32, i32), r: i32| -> Vec<[u8; 3]> {
        let mut px = Vec::new();
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let i = 4 * (y as usize * usize::from(w) + x as usize);
                px.push([frame[i], frame[i + 1], frame[i + 2]]);
            }
        }
        px
    };
    let traj = Columns::from(traj);
    let (first, last) = (0, traj.len() - 1);
    for k in [first, traj.len() / 2, last] {
        let at = layout.pixel_centre(traj.rows[k], traj.cols[k]);
        let px = near(&frames[traj.frames[k]], at, 2);
        assert!(
            px.contains(&[colour.0, colour.1, colour.2]),
            "no trajectory dot at {at:?} in frame {}",
            traj.frames[k]
        );
    }
    // Where the stroke starts, the picture differs between its first and last frame;
    // before the stroke, there is no dot there.
    let start = layout.pixel_centre(traj.rows[first], traj.cols[first]);
    assert_ne!(
        near(&frames[traj.frames[first]], start, 6),
        near(&frames[traj.frames[last]], start, 6)
    );
    if traj.frames[first] > 0 {
        let before = near(&frames[traj.frames[first] - 1], start, 2);
        assert!(!before.contains(&[colour.0, colour.1, colour.2]));
    }

    // --every 3 keeps every third frame, each shown three times as long.
    ok(&touchc(&[
        "preview",
        rec_path.to_str().unwrap(),
        "-o",
        gif_path.to_str().unwrap(),
        "--every",
        "3",
    ]));
    let (_, _, thinned, delays) = decode_gif(&gif_path);
    assert_eq!(thinned.len(), frames.len().div_ceil(3));
    assert_eq!(thinned[1], frames[3]);
    assert!(delays.iter().all(|&d| d == 15));
    // Frames after the first hold only what changed: the file is far smaller than
    // whole frames would make it (about 3 bits a pixel after LZW on this picture).
    let bytes = std::fs::metadata(&gif_path).unwrap().len() as usize;
    let whole = thinned.len() * usize::from(w) * usize::from(h);
    assert!(bytes * 4 < whole, "{bytes} bytes for {whole} px");
}

#[test]
fn preview_png_shows_one_frame_and_refuses_frames_past_the_end() {
    let dir = tempfile::tempdir().unwrap();
    let rec_path = dir.path().join("tap.npy");
    ok(&touchc(&["synth", "tap", "-o", rec_path.to_str().unwrap()]));
    let png_path = dir.path().join("tap.png");
    let args = |frame: &str| {
        touchc(&[
            "preview",
            rec_path.to_str().unwrap(),
            "-o",
            png_path.to_str().unwrap(),
            "--frame",
            frame,
        ])
    };
    ok(&args("30"));
    let (w, h, rgb) = decode_png(&png_path);
    assert!(w >= 496 && h > 200, "{w} x {h}");
    // The heat map (its 0 psi end) and the actuator panel's box outlines are drawn.
    let has = |c: [u8; 3]| rgb.chunks(3).any(|p| p == c);
    assert!(has([0, 0, 4]));
    assert!(has([120, 120, 120]));

    // The colour bar runs from the heat scale's 0 psi end (bottom row) to its maximum
    // (top row), brightening all the way.
    use touchc::viz::{palette::heat, preview};
    let rec = touchc_input::recording::Recording::load(&rec_path).unwrap();
    let opts = touchc_pipeline::compile::CompileOptions {
        fit: true,
        crop: false,
        keep_scene: true,
        ..Default::default()
    };
    let layout = preview::layout(&touchc_pipeline::compile::compile(&rec, &opts).unwrap()).unwrap();
    let px = |x: u32, y: u32| {
        let i = 3 * (y * w + x) as usize;
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    let (x0, y0, x1, y1) = layout.colour_bar;
    let mid = (x0 + x1) / 2;
    assert_eq!(px(mid, y0), heat(1.0));
    assert_eq!(px(mid, y1 - 1), heat(0.0));
    let sum = |c: [u8; 3]| c.iter().map(|&v| u32::from(v)).sum::<u32>();
    assert!((y0..y1 - 1).all(|y| sum(px(mid, y)) >= sum(px(mid, y + 1))));
    // Each row is one colour edge to edge, and the middle row is the middle of the scale
    // (within a row's step).
    assert!((y0..y1).all(|y| (x0..x1).all(|x| px(x, y) == px(mid, y))));
    let half = px(mid, (y0 + y1) / 2);
    let near = |f: f64| heat(f).iter().zip(half).all(|(&a, b)| a.abs_diff(b) <= 3);
    assert!(near(0.5), "{half:?} vs {:?}", heat(0.5));

    // Every legend entry has its text: light glyph pixels (anti-aliased white) right of
    // each of the six swatches, on the legend's dark band.
    let col_w = (w - 16) / 2;
    for k in 0..6u32 {
        let (tx, ty) = (
            8 + 6 + (k % 2) * col_w + 38,
            layout.legend_top + (k / 2) * 20,
        );
        let white = (ty..ty + 20)
            .flat_map(|y| (tx..tx + col_w - 50).map(move |x| (x, y)))
            .filter(|&(x, y)| px(x, y).iter().all(|&v| v >= 160))
            .count();
        assert!(white > 40, "legend entry {k}: {white} light px");
    }
    let out = args("100000");
    let err = refused(&out);
    assert!(err.contains("tap.npy") && err.contains("100000"), "{err}");
}

#[test]
fn preview_of_a_recording_without_touch_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let rec_path = dir.path().join("still.npy");
    let still = ndarray::Array3::<f64>::zeros((60, 8, 21));
    std::fs::write(&rec_path, touchc_synth::to_npy(&still).unwrap()).unwrap();
    let gif_path = dir.path().join("still.gif");
    let out = touchc(&[
        "preview",
        rec_path.to_str().unwrap(),
        "-o",
        gif_path.to_str().unwrap(),
    ]);
    let err = refused(&out);
    assert!(
        err.contains("still.npy") && err.contains("no touch"),
        "{err}"
    );
    assert!(!gif_path.exists());
}

/// Runs `touchc preview` on `rec_path` into a GIF next to it, and the compile the
/// command runs: (width, composited frames, recording, compile, frame layout).
fn preview_gif_and_compile(
    rec_path: &Path,
) -> (
    u16,
    Vec<Vec<u8>>,
    touchc_input::recording::Recording,
    touchc_pipeline::compile::Compiled,
    touchc::viz::preview::FrameLayout,
) {
    let gif_path = rec_path.with_extension("gif");
    ok(&touchc(&[
        "preview",
        "--preset",
        "paper",
        rec_path.to_str().unwrap(),
        "-o",
        gif_path.to_str().unwrap(),
    ]));
    let (w, _, frames, _) = decode_gif(&gif_path);
    let rec = touchc_input::recording::Recording::load(rec_path).unwrap();
    let opts = touchc_pipeline::compile::CompileOptions {
        fit: true,
        crop: false,
        keep_scene: true,
        config: touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper),
        ..Default::default()
    };
    let compiled = touchc_pipeline::compile::compile(&rec, &opts).unwrap();
    let layout = touchc::viz::preview::layout(&compiled).unwrap();
    (w, frames, rec, compiled, layout)
}

/// A recording whose touch is partly missed: a press held for 2 s (tracked) and, in the
/// middle of it, a one-frame blip at the far end of the sleeve (too brief for a
/// trajectory). 20 quiet frames before and after for the tare and trim.
fn press_and_blip() -> ndarray::Array3<f64> {
    let mut rec = ndarray::Array3::<f64>::zeros((100, 8, 21));
    let mut touch = |t: usize, r: usize, c: usize, psi: f64| {
        for (dr, dc, f) in [(0, 0, 1.0), (1, 0, 0.5), (0, 1, 0.5), (1, 1, 0.3)] {
            rec[[t, r + dr, c + dc]] += psi * f;
        }
    };
    for t in 25..65 {
        touch(t, 3, 4, 2.0);
    }
    touch(45, 5, 17, 2.0);
    rec
}

#[test]
fn preview_marks_touch_no_contact_explains_and_only_that() {
    use touchc::viz::preview;
    use touchc_pipeline::coverage::{self, Cell};

    let dir = tempfile::tempdir().unwrap();
    let rec_path = dir.path().join("blip.npy");
    std::fs::write(&rec_path, touchc_synth::to_npy(&press_and_blip()).unwrap()).unwrap();
    let (w, frames, rec, compiled, layout) = preview_gif_and_compile(&rec_path);

    // What the picture must show, from the coverage module on the compile's own
    // trajectories (the module is tested on its own in `coverage.rs`).
    let input = &compiled.report.config.input;
    let sampling =
        touchc_model::config::Sampling::new(&compiled.report.metadata, &compiled.report.config);
    let tared = rec.tare(input, &sampling).unwrap();
    let points = coverage::contact_points(
        &compiled.tracked.as_ref().unwrap().trajectories,
        compiled.report.config.preprocess.upsample,
    );
    let cells = coverage::classify(
        tared.view(),
        input.touch_threshold_psi,
        &points,
        coverage::DEFAULT_RADIUS_CELLS,
    );
    let count = |want: Cell| cells.iter().filter(|&&c| c == want).count();
    // The case is what it claims: the blip is missed, the press is explained.
    assert!(count(Cell::Unexplained) >= 4, "the blip is unexplained");
    assert!(count(Cell::Explained) > 100, "the press is tracked");
    assert!(cells
        .index_axis(ndarray::Axis(0), 25)
        .iter()
        .any(|&c| c == Cell::Unexplained));

    let red = preview::UNEXPLAINED;
    let (mut marked, mut clean) = (0, 0);
    for (t, frame) in frames.iter().enumerate() {
        for ((r, c), &cell) in cells.index_axis(ndarray::Axis(0), t).indexed_iter() {
            let (x0, y0, x1, y1) = layout.cell_rect(r, c);
            let reds = (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| {
                    let i = 4 * (y * usize::from(w) + x);
                    frame[i..i + 3] == [red.0, red.1, red.2]
                })
                .count();
            if cell == Cell::Unexplained {
                // Hatched: one pixel in six at least, outline or not.
                assert!(
                    reds >= (x1 - x0) * (y1 - y0) / 6,
                    "frame {t} cell ({r}, {c})"
                );
                marked += 1;
            } else {
                assert_eq!(reds, 0, "frame {t} cell ({r}, {c}) is {cell:?}");
                clean += 1;
            }
        }
    }
    assert_eq!(marked, count(Cell::Unexplained));
    assert!(clean > marked);

    // The PNG of the blip's frame says the coverage in its title band: pixels of text
    // are there, and the same frame's map carries the mark.
    let png_path = dir.path().join("blip.png");
    ok(&touchc(&[
        "preview",
        "--preset",
        "paper",
        rec_path.to_str().unwrap(),
        "-o",
        png_path.to_str().unwrap(),
        "--frame",
        "25",
    ]));
    let (pw, _, rgb) = decode_png(&png_path);
    let reds = rgb
        .chunks(3)
        .enumerate()
        .filter(|(i, p)| {
            let (x, y) = ((i % pw as usize) as u32, (i / pw as usize) as u32);
            y < layout.legend_top && x < layout.colour_bar.0 && *p == [red.0, red.1, red.2]
        })
        .count();
    assert!(reds > 50, "{reds} red px on the map");
}
