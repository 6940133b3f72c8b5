//! The pictures say what they show: the trade chart's time axis is labelled whatever
//! its range and the chart names its recording; the preview's text is evenly set, its
//! actuator strips have axes and legend entries, and its heat map shows typical
//! frames, not black.

use touchc::viz::trade::{log_ticks, plot_svg};
use touchc_eval::trade::TradeRow;
use touchc_model::config::Preset;
use touchc_model::stage::{Stage, StageSeconds};

fn row(input: &str, preset: Preset, ms: f64, rms: f64) -> TradeRow {
    let mut seconds = StageSeconds::default();
    seconds.add(Stage::Total, ms / 1000.0);
    TradeRow {
        input: input.to_string(),
        preset,
        seconds,
        transforms: (1, 1),
        score: 1.0,
        score_gap_pct: 0.0,
        rms_vs_exact_pct: rms,
        max_vs_exact_pct: rms,
        tracks_agree_pct: 100.0,
        bytes: 100,
        coverage: 1.0,
        rendered: 1.0,
        recall: None,
    }
}

/// The texts of an SVG's `<text>` elements.
fn svg_texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = &t[t.find('>')? + 1..];
            Some(body[..body.find("</text>")?].to_string())
        })
        .collect()
}

/// Times within one decade (40 to 120 ms) used to leave the log axis without a
/// single label; now it has several, each a tick inside the range; the title names
/// the recording, and every preset (four) has its points and its legend entry.
#[test]
fn the_trade_chart_labels_a_narrow_time_axis_and_names_its_recording() {
    let rows = vec![
        row("data/stroke.npy", Preset::Fast, 40.0, 3.0),
        row("data/stroke.npy", Preset::Paper, 70.0, 1.0),
        row("data/stroke.npy", Preset::Touch, 90.0, 2.0),
        row("data/stroke.npy", Preset::Exact, 120.0, 0.0),
    ];
    let svg = plot_svg(&rows).unwrap();
    let texts = svg_texts(&svg);
    let ticks: Vec<f64> = texts
        .iter()
        .filter_map(|t| t.trim().parse::<f64>().ok())
        .filter(|v| (40.0 / 1.5..=120.0 * 1.5).contains(v) && *v >= 20.0)
        .collect();
    assert!(ticks.len() >= 3, "time ticks {ticks:?} in {texts:?}");
    assert!(
        texts.iter().any(|t| t.contains("stroke.npy")),
        "no recording name in {texts:?}"
    );
    for preset in ["fast", "paper", "touch", "exact"] {
        assert!(
            texts.iter().any(|t| t.trim() == preset),
            "no legend entry {preset} in {texts:?}"
        );
    }
    // Several recordings: their count.
    let mut two = rows.clone();
    two.push(row("data/tap.npy", Preset::Exact, 80.0, 0.0));
    let texts = svg_texts(&plot_svg(&two).unwrap());
    assert!(
        texts.iter().any(|t| t.contains("2 recordings")),
        "{texts:?}"
    );
}

#[test]
fn log_ticks_label_any_range() {
    assert_eq!(
        log_ticks(26.0, 180.0),
        [30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0]
    );
    assert_eq!(
        log_ticks(0.5, 600.0),
        [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0]
    );
    assert!(log_ticks(5.0, 5.0).is_empty());
}

mod preview {
    use touchc::viz::preview::{self, png_frame, FrameLayout};
    use touchc_input::recording::Recording;
    use touchc_pipeline::compile::{compile, CompileOptions, Compiled};

    fn example(name: &str) -> (Recording, Compiled) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../examples")
            .join(name);
        let rec = Recording::load(path).unwrap();
        let opts = CompileOptions {
            crop: false,
            keep_scene: true,
            ..CompileOptions::default()
        };
        let compiled = compile(&rec, &opts).unwrap();
        (rec, compiled)
    }

    /// Frame `t` as (width, RGB pixels).
    fn frame(rec: &Recording, c: &Compiled, t: usize) -> (usize, Vec<[u8; 3]>) {
        let png = png_frame(c, rec, t, 20.0).unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(png))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        let px = buf[..info.buffer_size()]
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        (info.width as usize, px)
    }

    /// Mean brightness (0-255, the mean of R, G and B) of the heat map's pixels.
    fn map_brightness(l: &FrameLayout, w: usize, px: &[[u8; 3]]) -> f64 {
        let (x0, y0) = (l.map_origin.0 as usize, l.map_origin.1 as usize);
        let s = l.scale as usize;
        let (h, wd) = (l.map_px.0 * s, l.map_px.1 * s);
        let sum: u64 = (y0..y0 + h)
            .flat_map(|y| (x0..x0 + wd).map(move |x| (x, y)))
            .map(|(x, y)| px[y * w + x].iter().map(|&v| u64::from(v)).sum::<u64>())
            .sum();
        sum as f64 / (3 * h * wd) as f64
    }

    /// The example combination's touched frames (half its peak and more) used to be
    /// near black under a linear scale to the recording's maximum; on the scale now
    /// every one of them is clearly lit, while a frame without touch stays dark.
    #[test]
    fn heat_map_frames_with_touch_are_not_near_black() {
        let (rec, c) = example("combination.npy");
        let l = preview::layout(&c).unwrap();
        let frames = &c.tracked.as_ref().unwrap().blurred.frames;
        let peak = frames.iter().copied().fold(0.0f64, f64::max);
        let maxima: Vec<f64> = frames
            .outer_iter()
            .map(|f| f.iter().copied().fold(0.0f64, f64::max))
            .collect();
        let touched: Vec<usize> = (0..maxima.len())
            .filter(|&t| maxima[t] > 0.2 * peak)
            .step_by(8)
            .collect();
        assert!(touched.len() >= 5);
        for &t in &touched {
            let (w, px) = frame(&rec, &c, t);
            let b = map_brightness(&l, w, &px);
            assert!(
                b > 30.0,
                "frame {t} (peak {:.2} of {peak:.2} psi): brightness {b:.1}",
                maxima[t]
            );
        }
        let quiet = (0..maxima.len())
            .find(|&t| maxima[t] < 0.05 * peak)
            .unwrap();
        let (w, px) = frame(&rec, &c, quiet);
        assert!(map_brightness(&l, w, &px) < 30.0, "quiet frame {quiet}");
    }

    /// The legend has an entry for the actuator strips' curves (blue so far, grey
    /// ahead) and for their red line and intensity bar, and every strip has a psi axis
    /// (a vertical line up its left) beside its box and bar outlines.
    #[test]
    fn the_actuator_strips_have_axes_and_legend_entries() {
        let (rec, c) = example("tap_pat.npy");
        let l = preview::layout(&c).unwrap();
        let (w, px) = frame(&rec, &c, 40);
        let h = px.len() / w;
        let at = |x: usize, y: usize| px[y * w + x];
        let (blue, grey, red) = ([31, 119, 180], [200, 200, 200], [214, 39, 40]);
        // The legend's fourth row: its two swatches.
        let col_w = (w - 16) / 2;
        let row = l.legend_top as usize + 3 * 20;
        let swatch = |k: usize| {
            let x0 = 8 + 6 + k * col_w;
            (row..row + 20)
                .flat_map(|y| (x0..x0 + 30).map(move |x| (x, y)))
                .map(|(x, y)| at(x, y))
                .collect::<Vec<_>>()
        };
        let (curves, now) = (swatch(0), swatch(1));
        assert!(
            curves.contains(&blue) && curves.contains(&grey),
            "no curve swatch"
        );
        assert!(now.contains(&red), "no red-line swatch");
        // Light text right of each swatch, on the dark band.
        for k in 0..2 {
            let tx = 8 + 6 + k * col_w + 38;
            let light = (row..row + 20)
                .flat_map(|y| (tx..tx + col_w - 50).map(move |x| (x, y)))
                .filter(|&(x, y)| at(x, y).iter().all(|&v| v >= 160))
                .count();
            assert!(light > 40, "legend entry {}: {light} light px", 6 + k);
        }
        // Vertical runs of the outline grey at least 30 px long in the strips' rows:
        // per strip the box's two sides, the bar's two and the psi axis.
        let outline = [120, 120, 120];
        let top = h - 2 * 64 - 8;
        for strip_row in 0..2 {
            let (y0, y1) = (top + strip_row * 64, top + (strip_row + 1) * 64);
            let columns = (0..w)
                .filter(|&x| {
                    let mut run = 0;
                    (y0..y1).any(|y| {
                        run = if at(x, y) == outline { run + 1 } else { 0 };
                        run >= 30
                    })
                })
                .count();
            assert!(
                columns >= 5 * 4,
                "strip row {strip_row}: {columns} vertical lines"
            );
        }
    }
}
