//! `touchc plot`: the eight channels' currents against time, one panel per actuator,
//! laid out like the sleeve (row 0 on top, column 0 = elbow on the left), with the
//! stimulus's peak limit drawn in every panel.
//!
//! The traces are the [`Player`](touch_protocol::Player)'s output converted to amperes
//! ([`super::play`]), so a reviewer sees the ramps, the clamping and any fault exactly
//! as the sleeve would produce them, not the compiler's idealised signal. The ticks are
//! reduced while they stream to each channel's minimum and maximum per slice of time
//! (about one slice per pixel column), so a stimulus of any length plots in constant
//! memory and no peak falls between two drawn points.

use plotters::coord::Shift;
use plotters::prelude::*;
use touch_protocol::player::Fault;
use touch_protocol::{DeviceConfig, Stimulus, CHANNELS};

use super::{describe_fault, play, register_font, VizError, FAMILY};
use touchc_rendering::condition::OUTPUT_RATE_HZ;

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

/// Most points drawn per channel: about two per pixel column of the widest panel.
const MAX_POINTS: usize = 2000;

/// Plots `stimulus` as played on `device` (see [`super::play`]) and returns the file's
/// bytes.
pub fn plot(
    stimulus: &Stimulus<'_>,
    device: &DeviceConfig,
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
    // The header's length is the player's length but for a fault (shorter) or a
    // slew-limited ramp down (a little longer): slices stay about MAX_POINTS / 2.
    let expected = stimulus.header().playback_ms() as usize + 1;
    let mut ticks = play(stimulus, device);
    let mut trace = Trace::new(expected.div_ceil(MAX_POINTS / 2));
    for codes in &mut ticks {
        trace.push(codes);
    }
    trace.finish();
    let trace = Traced {
        points: trace.points.map(|p| {
            p.into_iter()
                .map(|(t, code)| (t as f64 / OUTPUT_RATE_HZ, ticks.amps(code)))
                .collect()
        }),
        biggest: [trace.low, trace.high]
            .iter()
            .map(|&code| ticks.amps(code).abs())
            .fold(0.0, f64::max),
        seconds: trace.ticks as f64 / OUTPUT_RATE_HZ,
        fault: ticks.fault(),
    };
    let dims = (size.width, size.height);
    match format {
        Format::Svg => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, dims).into_drawing_area();
                draw(&root, stimulus, &trace, Joins::Polyline).map_err(draw_error)?;
                root.present().map_err(draw_error)?;
            }
            Ok(svg.into_bytes())
        }
        Format::Png => {
            let mut rgb = vec![0u8; size.width as usize * size.height as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, dims).into_drawing_area();
                draw(&root, stimulus, &trace, Joins::Segments).map_err(draw_error)?;
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

/// What is drawn: each channel's reduced trace in (seconds, amperes).
struct Traced {
    points: [Vec<(f64, f64)>; CHANNELS],
    /// Largest absolute current on any channel, A.
    biggest: f64,
    seconds: f64,
    fault: Option<(usize, Fault)>,
}

/// How a wide trace is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Joins {
    /// One polyline per channel: the SVG's renderer joins its segments (with a miter
    /// limit) and the file stays small.
    Polyline,
    /// One path per segment, no joins: plotters' bitmap backend joins a wide polyline
    /// with unlimited inner miters, and where a min/max-reduced trace turns back on
    /// itself within a pixel or two (a long stimulus's spikes) the miter's point lies
    /// hundreds of pixels away, across the neighbouring panels.
    Segments,
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    stimulus: &Stimulus<'_>,
    trace: &Traced,
    joins: Joins,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let peak_a = f64::from(stimulus.limits().peak_ma) / 1000.0;
    // The name comes from the file: control characters would not render anyway.
    let name: String = stimulus
        .name()
        .chars()
        .map(|c| if c.is_control() { '\u{fffd}' } else { c })
        .collect();
    let mut title = format!(
        "{name}: {:.3} s played at 1 kHz, peak limit \u{b1}{:.2} A (red)",
        trace.seconds, peak_a
    );
    if let Some(f) = trace.fault {
        title.push_str("; ");
        title.push_str(&describe_fault(f));
    }
    let body = root.titled(&title, (FAMILY, 20))?;
    let t_end = trace.seconds.max(0.001);
    let y = (trace.biggest.max(peak_a) * 1.1).max(0.1);
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
        let style = TRACE.stroke_width(2);
        match joins {
            Joins::Polyline => {
                chart.draw_series(LineSeries::new(trace.points[ch].iter().copied(), style))?;
            }
            Joins::Segments => {
                chart.draw_series(
                    trace.points[ch]
                        .windows(2)
                        .map(|w| PathElement::new([w[0], w[1]], style)),
                )?;
            }
        }
    }
    Ok(())
}

/// A tick and its code.
type Point = (usize, u16);

/// Each channel's minimum and maximum per slice of `slice` ticks, in time order,
/// gathered as the ticks stream past.
struct Trace {
    slice: usize,
    ticks: usize,
    /// Per channel: (tick, code) of the slice's minimum and maximum so far.
    open: [Option<(Point, Point)>; CHANNELS],
    /// Per channel: the finished slices' points, as (tick, code).
    points: [Vec<Point>; CHANNELS],
    /// The last tick, drawn so a trace reaches the end.
    last: Option<[u16; CHANNELS]>,
    low: u16,
    high: u16,
}

impl Trace {
    fn new(slice: usize) -> Self {
        Trace {
            slice: slice.max(1),
            ticks: 0,
            open: [None; CHANNELS],
            points: std::array::from_fn(|_| Vec::new()),
            last: None,
            low: touch_protocol::IDLE_CODE,
            high: touch_protocol::IDLE_CODE,
        }
    }

    fn push(&mut self, codes: [u16; CHANNELS]) {
        let t = self.ticks;
        if t > 0 && t.is_multiple_of(self.slice) {
            self.close();
        }
        for (ch, &code) in codes.iter().enumerate() {
            let (lo, hi) = self.open[ch].get_or_insert(((t, code), (t, code)));
            if code < lo.1 {
                *lo = (t, code);
            }
            if code > hi.1 {
                *hi = (t, code);
            }
            self.low = self.low.min(code);
            self.high = self.high.max(code);
        }
        self.last = Some(codes);
        self.ticks += 1;
    }

    /// Ends the open slice: its extremes, earlier one first.
    fn close(&mut self) {
        for (open, points) in self.open.iter_mut().zip(&mut self.points) {
            if let Some((lo, hi)) = open.take() {
                let (a, b) = if lo.0 <= hi.0 { (lo, hi) } else { (hi, lo) };
                points.push(a);
                if b.0 != a.0 {
                    points.push(b);
                }
            }
        }
    }

    fn finish(&mut self) {
        self.close();
        if let Some(codes) = self.last {
            let t = self.ticks - 1;
            for (points, code) in self.points.iter_mut().zip(codes) {
                if points.last().is_none_or(|p| p.0 != t) {
                    points.push((t, code));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trace_keeps_extremes_of_long_signals_in_time_order() {
        let mut trace = Trace::new(10_000usize.div_ceil(50));
        for t in 0..10_000 {
            let mut codes = [2048; 8];
            codes[3] = match t {
                7777 => 4095,
                1234 => 0,
                _ => 2048,
            };
            trace.push(codes);
        }
        trace.finish();
        let pts = &trace.points[3];
        assert!(pts.len() <= 101, "{}", pts.len());
        assert!(pts.contains(&(7777, 4095)) && pts.contains(&(1234, 0)));
        assert!(pts.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(pts.last(), Some(&(9999, 2048)));
        assert_eq!((trace.low, trace.high), (0, 4095));
        // Short signals keep every tick.
        let mut short = Trace::new(1);
        for t in 0..5u16 {
            short.push([2048 + t; 8]);
        }
        short.finish();
        assert_eq!(
            short.points[0],
            (0..5).map(|t| (t, 2048 + t as u16)).collect::<Vec<_>>()
        );
    }
}
