//! The trade's chart (`touchc trade --svg`): time against error, from the rows
//! [`trade`](touchc_eval::trade::trade) measures.

use super::{register_font, VizError, FAMILY};
use touchc_eval::trade::TradeRow;
use touchc_model::config::Preset;

/// Tick values for a log axis over `lo..hi`: 1, 2 and 5 times the powers of ten
/// inside it, or every whole multiple of them (1 to 9) when that gives fewer than
/// three, so a range within one decade still has labelled ticks.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
        return Vec::new();
    }
    let decades = lo.log10().floor() as i32..=hi.log10().ceil() as i32;
    let within = |mantissas: &[f64]| -> Vec<f64> {
        decades
            .clone()
            .flat_map(|d| mantissas.iter().map(move |m| m * 10f64.powi(d)))
            .filter(|v| (lo..=hi).contains(v))
            .collect()
    };
    let coarse = within(&[1.0, 2.0, 5.0]);
    if coarse.len() >= 3 {
        coarse
    } else {
        within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    }
}

/// A tick value in its shortest form (`0.2`, `50`, `1000`), without the binary
/// representation's tail (`0.30000000000000004`).
fn tick_label(v: f64) -> String {
    let rounded = format!("{v:.6}");
    rounded
        .trim_end_matches('0')
        .trim_end_matches('.')
        .to_string()
}

/// What the chart's title names: the recording, or how many there are.
fn recordings_named(rows: &[TradeRow]) -> String {
    let mut names: Vec<&str> = rows.iter().map(|r| r.input.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    match names.as_slice() {
        [] => "no recording".to_string(),
        [one] => {
            let name = std::path::Path::new(one)
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or(one);
            // At most 60 characters, control and format characters shown as U+FFFD.
            let shown: String = name
                .chars()
                .map(|c| {
                    if c.is_control() || ('\u{200b}'..='\u{206f}').contains(&c) {
                        '\u{fffd}'
                    } else {
                        c
                    }
                })
                .collect();
            if shown.chars().count() > 60 {
                format!("{}\u{2026}", shown.chars().take(59).collect::<String>())
            } else {
                shown
            }
        }
        many => format!("{} recordings", many.len()),
    }
}

/// An SVG of time against error: total compile time (log scale) against the signal's
/// RMS difference to `exact`, one colour per preset, one point per recording and preset,
/// titled with the recording.
pub fn plot_svg(rows: &[TradeRow]) -> Result<String, VizError> {
    use plotters::prelude::*;

    register_font()?;
    let draw = |e: &dyn std::fmt::Display| VizError::Draw(e.to_string());
    let ms = |r: &TradeRow| 1e3 * r.seconds.total();
    let (lo, hi) = rows
        .iter()
        .map(ms)
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo < hi {
        (lo / 1.5, hi * 1.5)
    } else {
        (0.1, 1000.0)
    };
    let top = rows
        .iter()
        .map(|r| r.rms_vs_exact_pct)
        .filter(|v| v.is_finite())
        .fold(1.0f64, f64::max)
        * 1.1;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "touchc trade on {}: compile time against difference to exact",
                    recordings_named(rows)
                ),
                (FAMILY, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            // plotters labels a log axis at powers of ten only: none within a decade.
            .build_cartesian_2d(
                (lo..hi).log_scale().with_key_points(log_ticks(lo, hi)),
                0.0..top,
            )
            .map_err(|e| draw(&e))?;
        chart
            .configure_mesh()
            .x_desc("total compile time, ms (log)")
            .y_desc("RMS difference to exact, % of full scale")
            .x_label_formatter(&|v| tick_label(*v))
            .label_style((FAMILY, 12))
            .draw()
            .map_err(|e| draw(&e))?;
        // One per preset of `Preset::ALL`: a shorter list would drop the last ones.
        let colours: [RGBColor; Preset::ALL.len()] = [
            RGBColor(31, 119, 180),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
        ];
        for (preset, colour) in Preset::ALL.iter().zip(colours) {
            let points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.preset == *preset)
                .map(|r| (ms(r), r.rms_vs_exact_pct))
                .filter(|(x, y)| x.is_finite() && *x > 0.0 && y.is_finite())
                .collect();
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))
                .map_err(|e| draw(&e))?
                .label(preset.name())
                .legend(move |(x, y)| Circle::new((x + 8, y), 5, colour.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FAMILY, 13))
            .draw()
            .map_err(|e| draw(&e))?;
        root.present().map_err(|e| draw(&e))?;
    }
    Ok(svg)
}
