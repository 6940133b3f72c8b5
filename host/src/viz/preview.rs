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
//! GIF frames are palette images: a fixed 256-colour palette (the heat scale, greys and
//! the overlay colours) with a 32 x 32 x 32 nearest-colour table keeps every frame on one
//! global palette, deterministic and fast, where per-frame quantisation would flicker.

use std::borrow::Cow;

use plotters::prelude::*;

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
const BOX_PX: u32 = 40;
/// Room above a workspace circle for its channel label, px.
const LABEL_PX: u32 = 16;
/// Largest margin around the heat map, px.
const MAX_MARGIN_PX: u32 = 160;
/// Heat-map width the scale factor aims at, px.
const TARGET_WIDTH_PX: usize = 600;

/// Colours of the selected trajectories, in selection order (repeating); public so
/// tests and scripts can find them in the frames.
pub const TRAJECTORY_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 255, 0),
    RGBColor(0, 255, 255),
    RGBColor(255, 0, 255),
    RGBColor(255, 255, 255),
    RGBColor(90, 160, 255),
    RGBColor(255, 128, 0),
];
/// Unselected trajectories.
const OTHER: RGBColor = RGBColor(150, 150, 150);
/// Workspace circles whose actuator renders.
const ACTIVE: RGBColor = RGBColor(0, 255, 255);
/// Workspace circles whose actuator is silent.
const IDLE: RGBColor = RGBColor(255, 255, 255);

/// The margin around the map (one of the palette's greys).
const OFF_SENSOR: u8 = 47;

/// Heat-scale anchors (an inferno-like ramp: dark = 0 psi, pale yellow = maximum).
const HEAT: [(f64, [u8; 3]); 5] = [
    (0.0, [0, 0, 4]),
    (0.25, [87, 16, 110]),
    (0.5, [188, 55, 84]),
    (0.75, [249, 142, 9]),
    (1.0, [252, 255, 164]),
];
/// Palette entries spent on the heat scale; the rest are greys and overlay colours.
const HEAT_LEVELS: usize = 192;

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
        Ok(Scene {
            compiled,
            frames,
            pitch_mm: tracked.pitch_mm(),
            layout: FrameLayout::new(rows, cols, tracked.pitch_mm(), circles),
            vmax: if vmax > 0.0 { vmax } else { 1.0 },
            psi_max: if psi_max > 0.0 { psi_max } else { 1.0 },
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
    let palette = Palette::new();
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

/// The heat-scale colour of `x` in `[0, 1]`.
fn heat(x: f64) -> [u8; 3] {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let i = HEAT
        .iter()
        .rposition(|&(at, _)| at <= x)
        .unwrap_or(0)
        .min(HEAT.len() - 2);
    let ((x0, c0), (x1, c1)) = (HEAT[i], HEAT[i + 1]);
    let f = (x - x0) / (x1 - x0);
    std::array::from_fn(|k| {
        (f64::from(c0[k]) + f * (f64::from(c1[k]) - f64::from(c0[k]))).round() as u8
    })
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
    // The actuators in the sleeve's layout, with what each renders now.
    let top = (l.height - 2 * BOX_PX - PAD_PX) as i32;
    let box_w = ((l.width - 2 * PAD_PX) / 4) as i32;
    for ch in 0..CHANNELS {
        let (row, col) = ((ch / 4) as i32, (ch % 4) as i32);
        let (x0, y0) = (PAD_PX as i32 + col * box_w, top + row * BOX_PX as i32);
        let (psi, source) = match signals {
            Some(s) => (s.psi[ch][t], s.source[ch][t]),
            None => (0.0, Source::Silent),
        };
        let frac = (psi / scene.psi_max).clamp(0.0, 1.0);
        let [r, g, b] = heat(frac);
        let bar_w = ((box_w - 4) as f64 * frac).round() as i32;
        root.draw(&Rectangle::new(
            [(x0 + 2, y0 + 20), (x0 + 2 + bar_w, y0 + BOX_PX as i32 - 4)],
            RGBColor(r, g, b).filled(),
        ))?;
        root.draw(&Rectangle::new(
            [(x0 + 2, y0 + 2), (x0 + box_w - 2, y0 + BOX_PX as i32 - 4)],
            RGBColor(120, 120, 120).stroke_width(1),
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
    }
    Ok(())
}

/// The fixed GIF palette and its nearest-colour table.
struct Palette {
    /// 256 RGB triples, flat.
    rgb: Vec<u8>,
    /// Palette index per 5-bit-per-channel colour.
    table: Vec<u8>,
}

impl Palette {
    fn new() -> Palette {
        let mut colours: Vec<[u8; 3]> = (0..HEAT_LEVELS)
            .map(|i| heat(i as f64 / (HEAT_LEVELS - 1) as f64))
            .collect();
        colours.extend((0..=16).map(|i| [(i * 255 / 16) as u8; 3]));
        colours.extend(
            TRAJECTORY_COLOURS
                .iter()
                .chain([&OTHER, &ACTIVE, &IDLE])
                .map(|c| [c.0, c.1, c.2]),
        );
        // Fill the rest with a coarse colour cube for blends (text edges on the map).
        'cube: for r in [0u8, 128, 255] {
            for g in [0u8, 128, 255] {
                for b in [0u8, 128, 255] {
                    if colours.len() == 256 {
                        break 'cube;
                    }
                    colours.push([r, g, b]);
                }
            }
        }
        colours.resize(256, [0, 0, 0]);
        let table = (0..32 * 32 * 32)
            .map(|i| {
                let q = |shift: u32| ((i >> shift) & 31) * 8 + 4;
                let (r, g, b) = (q(10), q(5), q(0));
                let dist = |c: &[u8; 3]| {
                    let d = |a: u8, b: i32| (i32::from(a) - b).pow(2);
                    d(c[0], r) + d(c[1], g) + d(c[2], b)
                };
                (0..colours.len())
                    .min_by_key(|&k| dist(&colours[k]))
                    .unwrap_or(0) as u8
            })
            .collect();
        Palette {
            rgb: colours.concat(),
            table,
        }
    }

    fn indices(&self, rgb: &[u8]) -> Vec<u8> {
        rgb.chunks_exact(3)
            .map(|p| {
                let i = (usize::from(p[0] >> 3) << 10)
                    | (usize::from(p[1] >> 3) << 5)
                    | usize::from(p[2] >> 3);
                self.table[i]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_scale_runs_dark_to_pale_and_clamps() {
        assert_eq!(heat(0.0), [0, 0, 4]);
        assert_eq!(heat(1.0), [252, 255, 164]);
        assert_eq!(heat(2.0), heat(1.0));
        assert_eq!(heat(f64::NAN), heat(0.0));
        let sum = |c: [u8; 3]| c.iter().map(|&v| u32::from(v)).sum::<u32>();
        assert!((1..=20).all(|i| sum(heat(i as f64 / 20.0)) >= sum(heat((i - 1) as f64 / 20.0))));
    }

    #[test]
    fn palette_keeps_exact_overlay_colours() {
        let p = Palette::new();
        assert_eq!(p.rgb.len(), 768);
        for c in TRAJECTORY_COLOURS
            .iter()
            .chain([&OTHER, &ACTIVE, &IDLE, &RGBColor(0, 0, 0)])
        {
            let i = usize::from(p.indices(&[c.0, c.1, c.2])[0]);
            let got = &p.rgb[3 * i..3 * i + 3];
            let err: i32 = got
                .iter()
                .zip([c.0, c.1, c.2])
                .map(|(&a, b)| (i32::from(a) - i32::from(b)).abs())
                .sum();
            assert!(err <= 12, "{c:?} -> {got:?}");
        }
    }

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
