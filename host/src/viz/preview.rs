//! `touchc preview`: how a recording becomes actuator intensities, frame by frame (the
//! paper's Figure 4 b-e as an animation).
//!
//! Each frame shows, on the upsampled, blurred pressure map (one colour scale for the
//! whole recording, 0 psi to its maximum):
//! - every tracked trajectory's last second (20 frames) as a trail, and a dot where it
//!   is now; the trajectories placement selected in bright colours, the others grey;
//! - the eight workspace circles placement chose, drawn thick when their actuator
//!   renders at this frame;
//! - below, the eight actuators in the sleeve's layout (row 0 on top, column 0 = elbow
//!   on the left) with the pressure each renders (stage 5) as a bar, and whether it
//!   comes from a trajectory or from neighbour fill.
//!
//! The input is a [`Compiled`] run without the crop, so the frames are the recording's
//! frames after the tare and trim, one GIF frame each (or every `every`-th).
//! GIF frames are palette images on one fixed 256-colour palette shared by every frame,
//! so colours do not flicker from frame to frame.

use std::borrow::Cow;

use plotters::prelude::*;

use super::palette::{heat, Palette};
use super::plot::{draw_error, encode_png};
use super::{register_font, VizError, FAMILY};
use crate::compile::Compiled;
use crate::geometry::Circle;
use crate::signals::Source;
use touch_protocol::CHANNELS;

/// Frames of trail drawn behind a trajectory's current point (1 s at 20 Hz).
const TRAIL_FRAMES: usize = 20;
/// Height of the title band, px.
const TITLE_PX: u32 = 26;
/// Gap around the heat map and the actuator panel, px.
const PAD_PX: u32 = 8;
/// Height of one actuator's box in the panel below the map, px.
const BOX_PX: u32 = 64;
/// Width of the intensity bar in an actuator's box, px.
const BAR_PX: i32 = 10;
/// An actuator's signal ahead of the current frame.
const SPARK_AHEAD: RGBColor = RGBColor(200, 200, 200);
/// An actuator's signal up to the current frame.
const SPARK_PAST: RGBColor = RGBColor(31, 119, 180);
/// The current frame on the signal traces.
const CURSOR: RGBColor = RGBColor(214, 39, 40);
/// Outlines of the actuator boxes.
const BOX: RGBColor = RGBColor(120, 120, 120);
/// Room above a workspace circle for its channel label, px.
const LABEL_PX: u32 = 16;
/// Largest margin around the heat map, px.
const MAX_MARGIN_PX: u32 = 160;
/// Heat-map width the scale factor aims at, px.
const TARGET_WIDTH_PX: usize = 600;

/// Colours of the selected trajectories, in selection order (repeating); public so
/// tests and scripts can find them in the frames.
/// None of them is a circle colour (cyan for an actuator that renders, white otherwise).
pub const TRAJECTORY_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 255, 0),
    RGBColor(255, 0, 255),
    RGBColor(0, 120, 255),
    RGBColor(255, 255, 0),
    RGBColor(255, 128, 0),
    RGBColor(160, 255, 160),
];
/// Unselected trajectories.
const OTHER: RGBColor = RGBColor(150, 150, 150);
/// Workspace circles whose actuator renders.
const ACTIVE: RGBColor = RGBColor(0, 255, 255);
/// Workspace circles whose actuator is silent.
const IDLE: RGBColor = RGBColor(255, 255, 255);

/// The margin around the map (one of the palette's greys).
const OFF_SENSOR: u8 = 47;

/// Why a preview cannot be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PreviewError {
    /// The recording holds no touch: there is nothing tracked to show.
    #[error("the recording holds no touch: nothing was tracked, nothing to preview")]
    NoTouch,
    /// The compile ran with a crop: its blurred frames do not cover the recording.
    #[error("the compile was cropped to the active scene; preview needs the whole recording")]
    Cropped,
    /// A frame index past the end.
    #[error("frame {frame} does not exist: the recording has {frames} frames after the tare")]
    Frame {
        /// The frame asked for.
        frame: usize,
        /// Frames there are.
        frames: usize,
    },
    /// Drawing or encoding failed.
    #[error(transparent)]
    Viz(#[from] VizError),
}

/// Where things sit in a preview frame, so tests and scripts can find them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLayout {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Image px per blurred-map pixel.
    pub scale: u32,
    /// Top-left corner of the heat map in the image, px.
    pub map_origin: (u32, u32),
    /// Blurred-map size, (rows, cols) px.
    pub map_px: (usize, usize),
}

impl FrameLayout {
    /// The layout for a blurred map of `rows` x `cols` pixels of `pitch_mm`: the map
    /// scaled by an integer factor to about 600 px wide, with a margin wide enough for
    /// the workspace `circles` that reach past its edges (placement may put a row of
    /// circles partly off the sensor), and the actuator panel below.
    pub fn new(rows: usize, cols: usize, pitch_mm: f64, circles: &[Circle]) -> FrameLayout {
        let scale = (TARGET_WIDTH_PX / cols.max(1)).clamp(1, 16) as u32;
        let (mw, mh) = (cols as u32 * scale, rows as u32 * scale);
        let px_per_mm = f64::from(scale) / pitch_mm;
        let (w_mm, h_mm) = (f64::from(mw) / px_per_mm, f64::from(mh) / px_per_mm);
        let overshoot_mm = circles
            .iter()
            .flat_map(|c| {
                [
                    c.r_mm - c.x_mm,
                    c.x_mm + c.r_mm - w_mm,
                    c.r_mm - c.y_mm,
                    c.y_mm + c.r_mm - h_mm,
                ]
            })
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        // Room for the overshoot plus the circle's label; capped so that a far-off
        // layout cannot blow the image up.
        let margin =
            ((overshoot_mm * px_per_mm).ceil() as u32 + LABEL_PX).clamp(PAD_PX, MAX_MARGIN_PX);
        let width = (mw + 2 * margin).max(480 + 2 * PAD_PX);
        FrameLayout {
            width,
            height: TITLE_PX + mh + 2 * margin + 2 * BOX_PX + PAD_PX,
            scale,
            map_origin: ((width - mw) / 2, TITLE_PX + margin),
            map_px: (rows, cols),
        }
    }

    /// Image position of the centre of blurred-map pixel `(row, col)`.
    pub fn pixel_centre(&self, row: usize, col: usize) -> (i32, i32) {
        let s = self.scale as f64;
        (
            (self.map_origin.0 as f64 + (col as f64 + 0.5) * s) as i32,
            (self.map_origin.1 as f64 + (row as f64 + 0.5) * s) as i32,
        )
    }
}

/// What one preview needs from a compile, checked once.
struct Scene<'a> {
    compiled: &'a Compiled,
    frames: &'a ndarray::Array3<f64>,
    pitch_mm: f64,
    layout: FrameLayout,
    vmax: f64,
    psi_max: f64,
    /// Each actuator's whole signal as trace points (see [`traces`]).
    traces: [Vec<(i32, i32)>; CHANNELS],
}

impl<'a> Scene<'a> {
    fn new(compiled: &'a Compiled) -> Result<Self, PreviewError> {
        let (Some(tracked), Some(signals)) = (&compiled.tracked, &compiled.signals) else {
            return Err(PreviewError::NoTouch);
        };
        let frames = &tracked.blurred.frames;
        if frames.dim().0 != signals.frames() {
            return Err(PreviewError::Cropped);
        }
        let (_, rows, cols) = frames.dim();
        let circles = compiled
            .placement
            .as_ref()
            .map_or(&[][..], |p| &p.circles[..]);
        let finite_max =
            |it: &mut dyn Iterator<Item = f64>| it.filter(|v| v.is_finite()).fold(0.0f64, f64::max);
        let vmax = finite_max(&mut frames.iter().copied());
        let psi_max = finite_max(&mut signals.psi.iter().flatten().copied());
        let layout = FrameLayout::new(rows, cols, tracked.pitch_mm(), circles);
        let psi_max = if psi_max > 0.0 { psi_max } else { 1.0 };
        Ok(Scene {
            compiled,
            frames,
            pitch_mm: tracked.pitch_mm(),
            layout,
            vmax: if vmax > 0.0 { vmax } else { 1.0 },
            psi_max,
            traces: traces(&layout, &signals.psi, psi_max),
        })
    }

    fn count(&self) -> usize {
        self.frames.dim().0
    }
}

/// The layout of `compiled`'s preview frames (for tests and scripts).
pub fn layout(compiled: &Compiled) -> Result<FrameLayout, PreviewError> {
    Ok(Scene::new(compiled)?.layout)
}

/// The animation: one GIF frame per recording frame (every `every`-th, at least 1),
/// played at the recording's rate, looping.
pub fn gif(compiled: &Compiled, every: usize, frame_rate_hz: f64) -> Result<Vec<u8>, PreviewError> {
    register_font()?;
    let scene = Scene::new(compiled)?;
    let FrameLayout { width, height, .. } = scene.layout;
    let (w16, h16) = (
        u16::try_from(width).map_err(|_| too_big(width, height))?,
        u16::try_from(height).map_err(|_| too_big(width, height))?,
    );
    let palette = Palette::new(&[
        SPARK_AHEAD,
        SPARK_PAST,
        CURSOR,
        BOX,
        OTHER,
        ACTIVE,
        IDLE,
        TRAJECTORY_COLOURS[0],
        TRAJECTORY_COLOURS[1],
        TRAJECTORY_COLOURS[2],
        TRAJECTORY_COLOURS[3],
        TRAJECTORY_COLOURS[4],
        TRAJECTORY_COLOURS[5],
    ]);
    let every = every.max(1);
    // GIF delays are in hundredths of a second.
    let delay = (every as f64 * 100.0 / frame_rate_hz.max(1.0))
        .round()
        .clamp(1.0, 65535.0) as u16;
    let mut out = Vec::new();
    {
        let encode = |e: gif::EncodingError| VizError::Encode(e.to_string());
        let mut enc = gif::Encoder::new(&mut out, w16, h16, &palette.rgb).map_err(encode)?;
        enc.set_repeat(gif::Repeat::Infinite).map_err(encode)?;
        let mut rgb = vec![0u8; width as usize * height as usize * 3];
        for t in (0..scene.count()).step_by(every) {
            draw_frame(&scene, t, frame_rate_hz, &mut rgb)?;
            let frame = gif::Frame {
                width: w16,
                height: h16,
                delay,
                buffer: Cow::Owned(palette.indices(&rgb)),
                ..gif::Frame::default()
            };
            enc.write_frame(&frame).map_err(encode)?;
        }
    }
    Ok(out)
}

/// One frame as a PNG, to look at a moment closely.
pub fn png_frame(
    compiled: &Compiled,
    t: usize,
    frame_rate_hz: f64,
) -> Result<Vec<u8>, PreviewError> {
    register_font()?;
    let scene = Scene::new(compiled)?;
    if t >= scene.count() {
        return Err(PreviewError::Frame {
            frame: t,
            frames: scene.count(),
        });
    }
    let FrameLayout { width, height, .. } = scene.layout;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    draw_frame(&scene, t, frame_rate_hz, &mut rgb)?;
    Ok(encode_png(&rgb, width, height)?)
}

fn too_big(width: u32, height: u32) -> VizError {
    VizError::Size {
        width,
        height,
        min: 1,
        max: u32::from(u16::MAX),
    }
}

fn draw_frame(scene: &Scene<'_>, t: usize, rate_hz: f64, rgb: &mut [u8]) -> Result<(), VizError> {
    let l = scene.layout;
    rgb.fill(255);
    // Off the sensor: dark, so that circles reaching past the map stay visible.
    let margin = l.map_origin.0.min(l.map_origin.1 - TITLE_PX) as usize;
    let (mw, mh) = (l.map_px.1 * l.scale as usize, l.map_px.0 * l.scale as usize);
    for y in l.map_origin.1 as usize - margin..l.map_origin.1 as usize + mh + margin {
        let row = y * l.width as usize;
        let x0 = l.map_origin.0 as usize - margin;
        rgb[3 * (row + x0)..3 * (row + x0 + mw + 2 * margin)].fill(OFF_SENSOR);
    }
    // The heat map straight into the buffer: per-pixel drawing calls would cost more
    // than everything else in the frame.
    let frame = scene.frames.index_axis(ndarray::Axis(0), t);
    let s = l.scale as usize;
    for ((r, c), &v) in frame.indexed_iter() {
        let colour = heat(v / scene.vmax);
        for y in 0..s {
            let row = (l.map_origin.1 as usize + r * s + y) * l.width as usize;
            for x in 0..s {
                let i = 3 * (row + l.map_origin.0 as usize + c * s + x);
                rgb[i..i + 3].copy_from_slice(&colour);
            }
        }
    }
    let root = BitMapBackend::with_buffer(rgb, (l.width, l.height)).into_drawing_area();
    overlay(scene, t, rate_hz, &root).map_err(draw_error)?;
    root.present().map_err(draw_error)
}

type Area<'b> = DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>;
type DrawResult<'b> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'b> as DrawingBackend>::ErrorType>>;

fn overlay<'b>(scene: &Scene<'_>, t: usize, rate_hz: f64, root: &Area<'b>) -> DrawResult<'b> {
    let l = scene.layout;
    let c = scene.compiled;
    root.draw(&Text::new(
        format!(
            "{}  frame {}/{}  {:.2} s  (0 - {:.2} psi)",
            std::path::Path::new(&c.report.input)
                .file_name()
                .map_or(c.report.input.as_str(), |n| n.to_str().unwrap_or("")),
            t,
            scene.count(),
            t as f64 / rate_hz.max(1.0),
            scene.vmax
        ),
        (PAD_PX as i32, 5),
        (FAMILY, 16).into_font().color(&BLACK),
    ))?;
    let signals = c.signals.as_ref();
    let renders = |ch: usize| signals.is_some_and(|s| s.source[ch][t] != Source::Silent);
    if let Some(p) = &c.placement {
        let px_per_mm = f64::from(l.scale) / scene.pitch_mm;
        for (ch, circle) in p.circles.iter().enumerate() {
            let centre = (
                (f64::from(l.map_origin.0) + circle.x_mm * px_per_mm) as i32,
                (f64::from(l.map_origin.1) + circle.y_mm * px_per_mm) as i32,
            );
            let radius = (circle.r_mm * px_per_mm).round() as i32;
            let style = if renders(ch) {
                ACTIVE.stroke_width(3)
            } else {
                IDLE.stroke_width(1)
            };
            root.draw(&plotters::element::Circle::new(centre, radius, style))?;
            root.draw(&Text::new(
                format!("{ch}"),
                (centre.0 - 4, centre.1 - radius - 14),
                (FAMILY, 12).into_font().color(&IDLE),
            ))?;
        }
    }
    if let Some(tracked) = &c.tracked {
        let selected = c.placement.as_ref().map_or(&[][..], |p| &p.selected[..]);
        for (k, traj) in tracked.trajectories.iter().enumerate() {
            let colour = match selected.iter().position(|&s| s == k) {
                Some(i) => TRAJECTORY_COLOURS[i % TRAJECTORY_COLOURS.len()],
                None => OTHER,
            };
            let trail: Vec<(i32, i32)> = traj
                .frames
                .iter()
                .zip(traj.rows.iter().zip(&traj.cols))
                .filter(|(&f, _)| f <= t && f + TRAIL_FRAMES > t)
                .map(|(_, (&r, &c))| l.pixel_centre(r, c))
                .collect();
            if trail.len() > 1 {
                root.draw(&PathElement::new(trail.clone(), colour.stroke_width(2)))?;
            }
            if let Some(pos) = traj.frames.iter().position(|&f| f == t) {
                let at = l.pixel_centre(traj.rows[pos], traj.cols[pos]);
                root.draw(&plotters::element::Circle::new(at, 5, colour.filled()))?;
            }
        }
    }
    actuator_panel(scene, t, root)
}

/// Where actuator `ch`'s box sits: its top-left corner and width, px.
fn actuator_box(l: &FrameLayout, ch: usize) -> (i32, i32, i32) {
    let top = (l.height - 2 * BOX_PX - PAD_PX) as i32;
    let box_w = ((l.width - 2 * PAD_PX) / 4) as i32;
    let (row, col) = ((ch / 4) as i32, (ch % 4) as i32);
    (
        PAD_PX as i32 + col * box_w,
        top + row * BOX_PX as i32,
        box_w,
    )
}

/// The pixel rectangle `(x0, y0, x1, y1)` of actuator `ch`'s signal trace.
fn trace_rect(l: &FrameLayout, ch: usize) -> (i32, i32, i32, i32) {
    let (x0, y0, w) = actuator_box(l, ch);
    (
        x0 + 6,
        y0 + 20,
        x0 + w - BAR_PX - 10,
        y0 + BOX_PX as i32 - 8,
    )
}

/// Each channel's whole pressure signal as trace points, one per pixel column (the
/// column's largest value), so a frame draws a few hundred segments, not thousands.
fn traces(
    l: &FrameLayout,
    psi: &[Vec<f64>; CHANNELS],
    psi_max: f64,
) -> [Vec<(i32, i32)>; CHANNELS] {
    std::array::from_fn(|ch| {
        let (x0, y0, x1, y1) = trace_rect(l, ch);
        let mut points: Vec<(i32, i32)> = Vec::new();
        for (t, &v) in psi[ch].iter().enumerate() {
            let x = column(x0, x1, t, psi[ch].len());
            let y = y1 - ((y1 - y0) as f64 * (v / psi_max).clamp(0.0, 1.0)).round() as i32;
            match points.last_mut() {
                Some(last) if last.0 == x => last.1 = last.1.min(y),
                _ => points.push((x, y)),
            }
        }
        points
    })
}

/// The pixel column of frame `t` of `n` between `x0` and `x1`.
fn column(x0: i32, x1: i32, t: usize, n: usize) -> i32 {
    x0 + ((x1 - x0) as f64 * t as f64 / n.saturating_sub(1).max(1) as f64).round() as i32
}

/// The eight actuators in the sleeve's layout: what each renders now (value, source,
/// a heat-coloured bar) and its whole signal with a cursor at this frame.
fn actuator_panel<'b>(scene: &Scene<'_>, t: usize, root: &Area<'b>) -> DrawResult<'b> {
    let l = &scene.layout;
    let Some(signals) = scene.compiled.signals.as_ref() else {
        return Ok(());
    };
    for ch in 0..CHANNELS {
        let (x0, y0, box_w) = actuator_box(l, ch);
        let (psi, source) = (signals.psi[ch][t], signals.source[ch][t]);
        root.draw(&Rectangle::new(
            [(x0 + 2, y0 + 2), (x0 + box_w - 2, y0 + BOX_PX as i32 - 4)],
            BOX.stroke_width(1),
        ))?;
        let why = match source {
            Source::Silent => "",
            Source::Trajectory(_) => ", trajectory",
            Source::NeighbourFill => ", fill",
        };
        root.draw(&Text::new(
            format!("ch{ch}: {psi:.3} psi{why}"),
            (x0 + 6, y0 + 4),
            (FAMILY, 12).into_font().color(&BLACK),
        ))?;
        // The signal so far over the whole signal in grey, and a cursor at this frame.
        let (tx0, ty0, tx1, ty1) = trace_rect(l, ch);
        let now = column(tx0, tx1, t, scene.count());
        let trace = &scene.traces[ch];
        root.draw(&PathElement::new(
            trace.clone(),
            SPARK_AHEAD.stroke_width(1),
        ))?;
        let past: Vec<(i32, i32)> = trace.iter().copied().take_while(|p| p.0 <= now).collect();
        root.draw(&PathElement::new(past, SPARK_PAST.stroke_width(1)))?;
        root.draw(&PathElement::new(
            vec![(now, ty0), (now, ty1)],
            CURSOR.stroke_width(1),
        ))?;
        // Intensity now, as a bar rising from the bottom in the heat colour.
        let frac = (psi / scene.psi_max).clamp(0.0, 1.0);
        let [r, g, b] = heat(frac);
        let bar_top = ty1 - ((ty1 - ty0) as f64 * frac).round() as i32;
        let bar_x = x0 + box_w - BAR_PX - 6;
        root.draw(&Rectangle::new(
            [(bar_x, bar_top), (bar_x + BAR_PX, ty1)],
            RGBColor(r, g, b).filled(),
        ))?;
        root.draw(&Rectangle::new(
            [(bar_x, ty0), (bar_x + BAR_PX, ty1)],
            BOX.stroke_width(1),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_scales_the_paper_map_and_makes_room_for_circles() {
        let pitch = 25.4 / 7.0;
        let l = FrameLayout::new(56, 147, pitch, &[]);
        assert_eq!(l.scale, 4);
        assert_eq!(l.width, 147 * 4 + 2 * LABEL_PX);
        assert_eq!(l.map_origin, (LABEL_PX, TITLE_PX + LABEL_PX));
        assert_eq!(l.pixel_centre(0, 0), (16 + 2, 42 + 2));
        // A circle 10 mm past the top edge: the margin grows by its 11 px.
        let c = Circle {
            x_mm: 100.0,
            y_mm: 8.5,
            r_mm: 18.5,
            weight: 1.0,
        };
        let m = FrameLayout::new(56, 147, pitch, &[c]);
        let over = (10.0 * 4.0 / pitch).ceil() as u32;
        assert_eq!(m.map_origin.1, TITLE_PX + over + LABEL_PX);
        assert_eq!(m.height, l.height + 2 * over);
    }
}
