//! The pictures say what they show: the trade chart's time axis is labelled whatever
//! its range and the chart names its recording; the preview's text is evenly set, its
//! actuator strips have axes and legend entries, and its heat map shows typical
//! frames, not black.

use std::collections::BTreeMap;

use touchc::config::Preset;
use touchc::measure::trade::{log_ticks, plot_svg, TradeRow};

fn row(input: &str, preset: Preset, ms: f64, rms: f64) -> TradeRow {
    TradeRow {
        input: input.to_string(),
        preset,
        seconds: BTreeMap::from([("total", ms / 1000.0)]),
        transforms: (1, 1),
        score: 1.0,
        score_gap_pct: 0.0,
        rms_vs_exact_pct: rms,
        max_vs_exact_pct: rms,
        tracks_agree_pct: 100.0,
        bytes: 100,
        coverage: 1.0,
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
