//! `touchc plot`: the eight channels' currents against time, one panel per actuator,
//! laid out like the sleeve (row 0 on top, column 0 = elbow on the left), with the
//! stimulus's peak limit drawn in every panel.
//!
//! The traces are the [`Player`](touch_protocol::Player)'s output converted to amperes
//! ([`super::play`]), so a reviewer sees the ramps, the clamping and any fault exactly
//! as the sleeve would produce them, not the compiler's idealised signal.

use plotters::coord::Shift;
use plotters::prelude::*;
use touch_protocol::{Stimulus, CHANNELS};

use super::{register_font, Playback, VizError, FAMILY};

/// Actuator rows on the sleeve (`channel = row * COLUMNS + column`).
const ROWS: usize = 2;
/// Actuator columns on the sleeve; column 0 is nearest the elbow.
const COLUMNS: usize = 4;

/// The trace colour: used for nothing else, so a test (or a script) can find traces.
pub const TRACE: RGBColor = RGBColor(31, 119, 180);
/// The peak-limit lines' colour.
pub const LIMIT: RGBColor = RGBColor(214, 39, 40);

/// Smallest and largest image side, px: below the minimum the eight panels' labels no
/// longer fit; above the maximum a PNG buffer grows past what a plot needs.
pub const SIDE_PX: (u32, u32) = (320, 8000);

/// Which file kind to produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Scalable vector graphics: for papers and zooming into long stimuli.
    Svg,
    /// A PNG bitmap: for chat, issues and quick looks.
    Png,
}

impl Format {
    /// Picks the format from a file name's extension (`.svg`, `.png`, any case), so the
    /// output name is the only choice a user makes.
    pub fn from_extension(path: &std::path::Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "svg" => Some(Format::Svg),
            "png" => Some(Format::Png),
            _ => None,
        }
    }
}

/// Size of the picture, px.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

impl Default for Size {
    /// Wide enough for a 4-column sleeve with readable axes on a laptop screen.
    fn default() -> Self {
        Size {
            width: 1600,
            height: 800,
        }
    }
}

/// Plots `stimulus` as played by `playback` (see [`super::play`]) and returns the
/// file's bytes.
pub fn plot(
    stimulus: &Stimulus<'_>,
    playback: &Playback,
    format: Format,
    size: Size,
) -> Result<Vec<u8>, VizError> {
    let (min, max) = SIDE_PX;
    if !(min..=max).contains(&size.width) || !(min..=max).contains(&size.height) {
        return Err(VizError::Size {
            width: size.width,
            height: size.height,
            min,
            max,
        });
    }
    register_font()?;
    let dims = (size.width, size.height);
    match format {
        Format::Svg => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, dims).into_drawing_area();
                draw(&root, stimulus, playback).map_err(draw_error)?;
                root.present().map_err(draw_error)?;
            }
            Ok(svg.into_bytes())
        }
        Format::Png => {
            let mut rgb = vec![0u8; size.width as usize * size.height as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, dims).into_drawing_area();
                draw(&root, stimulus, playback).map_err(draw_error)?;
                root.present().map_err(draw_error)?;
            }
            encode_png(&rgb, size.width, size.height)
        }
    }
}

/// Encodes an RGB8 buffer as PNG (the preview's still frames use this too).
pub(crate) fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, VizError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let encode = |e: png::EncodingError| VizError::Encode(e.to_string());
    let mut writer = enc.write_header().map_err(encode)?;
    writer.write_image_data(rgb).map_err(encode)?;
    writer.finish().map_err(encode)?;
    Ok(out)
}

pub(crate) fn draw_error(e: impl std::fmt::Display) -> VizError {
    VizError::Draw(e.to_string())
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    stimulus: &Stimulus<'_>,
    playback: &Playback,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let peak_a = f64::from(stimulus.limits().peak_ma) / 1000.0;
    let mut title = format!(
        "{}: {:.3} s played at 1 kHz, peak limit \u{b1}{:.2} A (red)",
        stimulus.name(),
        playback.seconds(),
        peak_a
    );
    if let Some((t, f)) = playback.fault {
        title.push_str(&format!(
            "; {:?} limit hit on ch{} at {:.3} s, ramped down",
            f.kind,
            f.channel,
            t as f64 / 1000.0
        ));
    }
    let body = root.titled(&title, (FAMILY, 20))?;
    let t_end = playback.seconds().max(0.001);
    let biggest = (0..CHANNELS)
        .flat_map(|ch| (0..playback.codes.len()).map(move |t| (t, ch)))
        .map(|(t, ch)| playback.amps(t, ch).abs())
        .fold(peak_a, f64::max);
    let y = (biggest * 1.1).max(0.1);
    let panels = body.split_evenly((ROWS, COLUMNS));
    for (ch, panel) in panels.iter().enumerate() {
        let (row, col) = (ch / COLUMNS, ch % COLUMNS);
        let mut caption = format!("ch{ch}: row {row}, column {col}");
        if col == 0 {
            caption.push_str(" (elbow)");
        }
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, (FAMILY, 15))
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(48)
            .build_cartesian_2d(0f64..t_end, -y..y)?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .x_desc("time, s")
            .y_desc("current, A")
            .x_labels(5)
            .y_labels(5)
            .label_style((FAMILY, 12))
            .draw()?;
        for level in [peak_a, -peak_a] {
            chart.draw_series(LineSeries::new(
                [(0.0, level), (t_end, level)],
                LIMIT.stroke_width(1),
            ))?;
        }
        chart.draw_series(LineSeries::new(
            envelope(playback, ch, 2000),
            TRACE.stroke_width(2),
        ))?;
    }
    Ok(())
}

/// Channel `ch` as (seconds, amperes) points; longer than `max_points` ticks, it keeps
/// each bucket's minimum and maximum in time order, so a long stimulus stays light in
/// SVG and no peak disappears between two drawn points.
fn envelope(playback: &Playback, ch: usize, max_points: usize) -> Vec<(f64, f64)> {
    let n = playback.codes.len();
    let at = |t: usize| (t as f64 / 1000.0, playback.amps(t, ch));
    if n <= max_points {
        return (0..n).map(at).collect();
    }
    let buckets = (max_points / 2).max(1);
    let mut out = Vec::with_capacity(2 * buckets + 1);
    for b in 0..buckets {
        let (lo, hi) = (
            b * n / buckets,
            ((b + 1) * n / buckets).max(b * n / buckets + 1),
        );
        let (mut tmin, mut tmax) = (lo, lo);
        for t in lo..hi.min(n) {
            if playback.amps(t, ch) < playback.amps(tmin, ch) {
                tmin = t;
            }
            if playback.amps(t, ch) > playback.amps(tmax, ch) {
                tmax = t;
            }
        }
        out.push(at(tmin.min(tmax)));
        out.push(at(tmin.max(tmax)));
    }
    out.push(at(n - 1));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use touch_protocol::DeviceConfig;

    #[test]
    fn envelope_keeps_extremes_of_long_signals() {
        let codes: Vec<[u16; 8]> = (0..10_000)
            .map(|t| [if t == 7777 { 4095 } else { 2048 }; 8])
            .collect();
        let pb = Playback {
            codes,
            device: DeviceConfig::default(),
            fault: None,
        };
        let pts = envelope(&pb, 3, 100);
        assert!(pts.len() <= 101);
        assert!(pts.iter().any(|&(t, a)| t == 7.777 && a > 0.99));
        assert!(pts.windows(2).all(|w| w[0].0 <= w[1].0));
    }
}
