//! `touchc preview`: how a recording becomes actuator intensities, frame by frame (the
//! paper's Figure 4 b-e as an animation).
//!
//! Each frame shows, on the upsampled, blurred pressure map (one colour scale for the
//! whole recording, 0 psi to its maximum, drawn as a colour bar beside the map):
//! - every tracked trajectory's last second (20 frames) as a trail, and a dot where it
//!   is now; the trajectories placement selected in bright colours, the others grey;
//! - the eight workspace circles placement chose, drawn thick when their actuator
//!   renders at this frame;
//! - the touch no contact explains, hatched and outlined in red per sensor cell: the
//!   readings [`coverage::classify`] finds more than [`DEFAULT_RADIUS_CELLS`] cells from
//!   every tracked contact of the same frame, so a missed touch is never silent in a
//!   picture; the title gives the recording's coverage;
//! - under the map, the arm's orientation (column 0 at the elbow, on the left) and a mm
//!   scale bar; a legend for every marker;
//! - below, the eight actuators in the sleeve's layout (row 0 on top, column 0 = elbow
//!   on the left) with the pressure each renders (stage 5) as a bar, and whether it
//!   comes from a trajectory or from neighbour fill.
//!
//! The input is a [`Compiled`] run without the crop, so the frames are the recording's
//! frames after the tare and trim, one GIF frame each (or every `every`-th). The compile
//! may keep its blurred movie (`keep_scene`) or not: without it each frame is blurred
//! again as it is drawn (bit for bit the compile's: the same operator on the same
//! frame), so a preview's memory follows one frame, not the recording's length.
//! GIF frames are palette images on one fixed 256-colour palette shared by every frame,
//! so colours do not flicker from frame to frame; after the first, each frame holds only
//! the rectangle that changed, with the pixels that stayed the same transparent.

use ndarray::{Array3, Axis};
use plotters::prelude::*;

use super::palette::heat;
use super::plot::draw_error;
use super::VizError;
use touch_protocol::CHANNELS;
use touchc_input::recording::{Recording, RecordingError};
use touchc_model::config::Sampling;
use touchc_model::geometry::Circle;
use touchc_pipeline::compile::Compiled;
use touchc_pipeline::coverage::{self, Cell, Coverage, DEFAULT_RADIUS_CELLS};
use touchc_tracking::preprocess::{Blur, BlurOperator, PreprocessError};

mod draw;
mod encode;

use draw::{legend_band, mark_unexplained, overlay, swatch_rect, traces};

pub use encode::{gif, png_frame};

/// Frames of trail drawn behind a trajectory's current point (1 s at 20 Hz).
const TRAIL_FRAMES: usize = 20;
/// Height of the title band (two lines), px.
const TITLE_PX: u32 = 44;
/// Gap around the heat map and the actuator panel, px.
const PAD_PX: u32 = 8;
/// Height of the band under the map with the arm's ends and the mm scale bar, px.
const ORIENT_PX: u32 = 32;
/// Height of one legend row, px.
const LEGEND_ROW_PX: u32 = 20;
/// Legend rows (two entries each).
const LEGEND_ROWS: u32 = 4;
/// Height of one actuator's box in the panel below the map, px.
const BOX_PX: u32 = 64;
/// Width of the intensity bar in an actuator's box, px.
const BAR_PX: i32 = 10;
/// Room right of the map's margin for the colour bar and its labels, px.
const COLOUR_BAR_ROOM_PX: u32 = 92;
/// Gap between the map's margin and the colour bar, px.
const COLOUR_BAR_GAP_PX: u32 = 10;
/// Width of the colour bar itself, px.
const COLOUR_BAR_PX: u32 = 16;
/// Spacing of the hatch lines over unexplained touch, px.
const HATCH_PX: usize = 6;
/// Width of the outline around unexplained touch, px.
const OUTLINE_PX: usize = 2;
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
/// None of them is a circle colour (cyan for an actuator that renders, white otherwise)
/// or [`UNEXPLAINED`].
pub const TRAJECTORY_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 255, 0),
    RGBColor(255, 0, 255),
    RGBColor(0, 120, 255),
    RGBColor(255, 255, 0),
    RGBColor(255, 128, 0),
    RGBColor(160, 255, 160),
];
/// The hatching and outline of touch no contact explains: a pure red the heat scale
/// never reaches (its reds are dull crimson and orange) and nothing else on the map
/// uses; public so tests and scripts can find the marks.
pub const UNEXPLAINED: RGBColor = RGBColor(255, 0, 0);
/// Unselected trajectories.
const OTHER: RGBColor = RGBColor(150, 150, 150);
/// Workspace circles whose actuator renders.
const ACTIVE: RGBColor = RGBColor(0, 255, 255);
/// Workspace circles whose actuator is silent.
const IDLE: RGBColor = RGBColor(255, 255, 255);

/// The margin around the map and the legend's background (one of the palette's greys).
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
    /// The recording given is not the one compiled (its tared size differs).
    #[error(
        "the recording does not match the compile: {tared:?} tared readings, \
         {blurred:?} blurred pixels at {upsample}x"
    )]
    Mismatch {
        /// Tared recording `[frames, rows, cols]`.
        tared: (usize, usize, usize),
        /// Blurred movie `[frames, rows, cols]`.
        blurred: (usize, usize, usize),
        /// The compile's upsampling factor.
        upsample: usize,
    },
    /// A frame index past the end.
    #[error("frame {frame} does not exist: the recording has {frames} frames after the tare")]
    Frame {
        /// The frame asked for.
        frame: usize,
        /// Frames there are.
        frames: usize,
    },
    /// The recording could not be tared.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The compile's blur cannot be built again (its parameters were checked by the
    /// compile, so this means the compile given is not of this recording).
    #[error(transparent)]
    Blur(#[from] PreprocessError),
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
    /// Blurred-map pixels per sensor cell (the compile's upsampling factor).
    pub upsample: usize,
    /// Top-left corner of the heat map in the image, px.
    pub map_origin: (u32, u32),
    /// Blurred-map size, (rows, cols) px.
    pub map_px: (usize, usize),
    /// The dark margin around the map, px (room for circles reaching past it).
    pub margin: u32,
    /// The colour bar, `[x0, x1) x [y0, y1)` as `(x0, y0, x1, y1)`: the 0 psi end is
    /// its bottom row, the maximum its top row.
    pub colour_bar: (u32, u32, u32, u32),
    /// Top of the band with the arm's ends and the scale bar, px.
    pub orient_top: u32,
    /// Top of the legend, px.
    pub legend_top: u32,
}

impl FrameLayout {
    /// The layout for a blurred map of `rows` x `cols` pixels of `pitch_mm` (`upsample`
    /// pixels per sensor cell): the map scaled by an integer factor to about 600 px
    /// wide, with a margin wide enough for the workspace `circles` that reach past its
    /// edges (placement may put a row of circles partly off the sensor), the colour bar
    /// on its right, the orientation band and the legend under it, and the actuator
    /// panel below.
    pub fn new(
        rows: usize,
        cols: usize,
        upsample: usize,
        pitch_mm: f64,
        circles: &[Circle],
    ) -> FrameLayout {
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
        let width = (mw + 2 * margin + COLOUR_BAR_ROOM_PX).max(480 + 2 * PAD_PX);
        let map_origin = ((width - COLOUR_BAR_ROOM_PX - mw) / 2, TITLE_PX + margin);
        let bar_x = map_origin.0 + mw + margin + COLOUR_BAR_GAP_PX;
        let orient_top = map_origin.1 + mh + margin;
        let legend_top = orient_top + ORIENT_PX;
        FrameLayout {
            width,
            height: legend_top + LEGEND_ROWS * LEGEND_ROW_PX + PAD_PX + 2 * BOX_PX + PAD_PX,
            scale,
            upsample: upsample.max(1),
            map_origin,
            map_px: (rows, cols),
            margin,
            colour_bar: (
                bar_x,
                map_origin.1,
                bar_x + COLOUR_BAR_PX,
                map_origin.1 + mh,
            ),
            orient_top,
            legend_top,
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

    /// The image rectangle `(x0, y0, x1, y1)`, half-open, of sensor cell `(row, col)`.
    pub fn cell_rect(&self, row: usize, col: usize) -> (usize, usize, usize, usize) {
        let side = self.upsample * self.scale as usize;
        let (x0, y0) = (
            self.map_origin.0 as usize + col * side,
            self.map_origin.1 as usize + row * side,
        );
        (x0, y0, x0 + side, y0 + side)
    }
}

/// What one preview needs from a compile, checked once.
struct Scene<'a> {
    compiled: &'a Compiled,
    frames: Movie<'a>,
    pitch_mm: f64,
    layout: FrameLayout,
    vmax: f64,
    psi_max: f64,
    /// Each actuator's whole signal as trace points (see [`traces`]).
    traces: [Vec<(i32, i32)>; CHANNELS],
    /// Every tared reading classified against the tracked contacts.
    cells: Array3<Cell>,
    /// The recording's coverage by those contacts.
    coverage: Coverage,
}

impl<'a> Scene<'a> {
    fn new(compiled: &'a Compiled, recording: &Recording) -> Result<Self, PreviewError> {
        let (kept, layout) = checked(compiled)?;
        let tracked = compiled.tracked.as_ref().ok_or(PreviewError::NoTouch)?;
        let signals = compiled.signals.as_ref().ok_or(PreviewError::NoTouch)?;
        let input = &compiled.report.config.input;
        // The sampling the compile used (its report carries the resolved metadata).
        let sampling = Sampling::new(&compiled.report.metadata, &compiled.report.config);
        let tared = recording.tare(input, &sampling)?;
        let (t, r, c) = tared.dim();
        let k = layout.upsample;
        let blurred = (signals.frames(), layout.map_px.0, layout.map_px.1);
        if blurred != (t, r * k, c * k) {
            return Err(PreviewError::Mismatch {
                tared: tared.dim(),
                blurred,
                upsample: k,
            });
        }
        let points = coverage::contact_points(&tracked.trajectories, k);
        let threshold = input.touch_threshold_psi;
        let cells = coverage::classify(tared.view(), threshold, &points, DEFAULT_RADIUS_CELLS);
        let coverage = coverage::measure(tared.view(), threshold, &points, DEFAULT_RADIUS_CELLS);
        let finite_max =
            |it: &mut dyn Iterator<Item = f64>| it.filter(|v| v.is_finite()).fold(0.0f64, f64::max);
        let frames = match kept {
            Some(movie) => Movie::Kept(movie),
            None => Movie::Streamed {
                op: Box::new(BlurOperator::new(
                    r,
                    c,
                    &Blur::new(&compiled.report.config.preprocess, &sampling),
                )?),
                tared,
            },
        };
        let vmax = match &frames {
            Movie::Kept(movie) => finite_max(&mut movie.iter().copied()),
            // One frame at a time: the colour scale's top without the movie.
            Movie::Streamed { .. } => (0..t)
                .map(|f| finite_max(&mut frames.frame(f).iter().copied()))
                .fold(0.0, f64::max),
        };
        let psi_max = finite_max(&mut signals.psi.iter().flatten().copied());
        let psi_max = if psi_max > 0.0 { psi_max } else { 1.0 };
        Ok(Scene {
            compiled,
            frames,
            pitch_mm: tracked.pitch_mm(),
            layout,
            vmax: if vmax > 0.0 { vmax } else { 1.0 },
            psi_max,
            traces: traces(&layout, &signals.psi, psi_max),
            cells,
            coverage,
        })
    }

    fn count(&self) -> usize {
        self.frames.count()
    }
}

/// The blurred frames a preview draws: the compile's movie, or each frame blurred again
/// from the tared recording when it is drawn.
enum Movie<'a> {
    Kept(&'a ndarray::Array3<f64>),
    Streamed {
        tared: ndarray::Array3<f64>,
        op: Box<BlurOperator>,
    },
}

impl Movie<'_> {
    fn count(&self) -> usize {
        match self {
            Movie::Kept(movie) => movie.dim().0,
            Movie::Streamed { tared, .. } => tared.dim().0,
        }
    }

    /// Blurred frame `t` (in range).
    fn frame(&self, t: usize) -> ndarray::CowArray<'_, f64, ndarray::Ix2> {
        match self {
            Movie::Kept(movie) => movie.index_axis(Axis(0), t).into(),
            Movie::Streamed { tared, op } => op.apply(tared.index_axis(Axis(0), t)).into(),
        }
    }
}

/// The blurred movie of an uncropped compile with touch (`None` when the compile
/// streamed and kept none), and its frames' layout.
fn checked(
    compiled: &Compiled,
) -> Result<(Option<&ndarray::Array3<f64>>, FrameLayout), PreviewError> {
    let (Some(tracked), Some(signals)) = (&compiled.tracked, &compiled.signals) else {
        return Err(PreviewError::NoTouch);
    };
    let frames = &tracked.blurred.frames;
    let (kept, rows, cols) = frames.dim();
    let upsample = compiled.report.config.preprocess.upsample;
    // Without the movie, the compile's crop says whether it saw the whole recording.
    let whole = compiled.report.crop.as_ref().is_some_and(|crop| {
        crop.frames == (0..signals.frames())
            && crop.rows.start == 0
            && crop.rows.len() * upsample == rows
            && crop.cols.start == 0
            && crop.cols.len() * upsample == cols
    });
    let movie = if kept == signals.frames() {
        Some(frames)
    } else if kept == 0 && whole {
        None
    } else {
        return Err(PreviewError::Cropped);
    };
    let circles = compiled
        .placement
        .as_ref()
        .map_or(&[][..], |p| &p.circles[..]);
    let layout = FrameLayout::new(rows, cols, upsample, tracked.pitch_mm(), circles);
    Ok((movie, layout))
}

/// The layout of `compiled`'s preview frames (for tests and scripts).
pub fn layout(compiled: &Compiled) -> Result<FrameLayout, PreviewError> {
    Ok(checked(compiled)?.1)
}

/// An RGB8 image buffer with its width, for the fills plotters would draw pixel by pixel.
struct Canvas<'b> {
    rgb: &'b mut [u8],
    width: usize,
}

impl Canvas<'_> {
    fn set(&mut self, x: usize, y: usize, colour: [u8; 3]) {
        let i = 3 * (y * self.width + x);
        self.rgb[i..i + 3].copy_from_slice(&colour);
    }

    /// Fills the half-open rectangle `[x0, x1) x [y0, y1)`.
    fn fill(&mut self, (x0, y0, x1, y1): (usize, usize, usize, usize), colour: [u8; 3]) {
        for y in y0..y1 {
            let row = 3 * y * self.width;
            self.rgb[row + 3 * x0..row + 3 * x1]
                .chunks_exact_mut(3)
                .for_each(|p| p.copy_from_slice(&colour));
        }
    }

    /// Diagonal hatch lines over the rectangle, aligned to the image so that the lines
    /// run on across neighbouring rectangles.
    fn hatch(&mut self, (x0, y0, x1, y1): (usize, usize, usize, usize), colour: [u8; 3]) {
        for y in y0..y1 {
            for x in (x0..x1).filter(|x| (x + y) % HATCH_PX == 0) {
                self.set(x, y, colour);
            }
        }
    }
}

fn draw_frame(scene: &Scene<'_>, t: usize, rate_hz: f64, rgb: &mut [u8]) -> Result<(), VizError> {
    let l = scene.layout;
    rgb.fill(255);
    let mut canvas = Canvas {
        rgb,
        width: l.width as usize,
    };
    let (ox, oy) = (l.map_origin.0 as usize, l.map_origin.1 as usize);
    // Off the sensor: dark, so that circles reaching past the map stay visible.
    let margin = l.margin as usize;
    let (mw, mh) = (l.map_px.1 * l.scale as usize, l.map_px.0 * l.scale as usize);
    canvas.fill(
        (ox - margin, oy - margin, ox + mw + margin, oy + mh + margin),
        [OFF_SENSOR; 3],
    );
    // The heat map straight into the buffer: per-pixel drawing calls would cost more
    // than everything else in the frame.
    let frame = scene.frames.frame(t);
    let s = l.scale as usize;
    for ((r, c), &v) in frame.indexed_iter() {
        let (x, y) = (ox + c * s, oy + r * s);
        canvas.fill((x, y, x + s, y + s), heat(v / scene.vmax));
    }
    mark_unexplained(&mut canvas, &l, scene.cells.index_axis(Axis(0), t));
    // The colour bar: the heat scale from 0 psi (bottom row) to the maximum (top row).
    let (bx0, by0, bx1, by1) = l.colour_bar;
    for y in by0..by1 {
        let x = f64::from(by1 - 1 - y) / f64::from((by1 - by0).max(2) - 1);
        let (y, x0, x1) = (y as usize, bx0 as usize, bx1 as usize);
        canvas.fill((x0, y, x1, y + 1), heat(x));
    }
    // The legend's dark band (the idle circles are white) and its hatched swatch.
    let band = legend_band(&l);
    canvas.fill(band, [OFF_SENSOR; 3]);
    let swatch = swatch_rect(&l, 4);
    canvas.hatch(swatch, rgb_of(UNEXPLAINED));
    let root = BitMapBackend::with_buffer(rgb, (l.width, l.height)).into_drawing_area();
    overlay(scene, t, rate_hz, &root).map_err(draw_error)?;
    root.present().map_err(draw_error)
}

fn rgb_of(c: RGBColor) -> [u8; 3] {
    [c.0, c.1, c.2]
}

#[cfg(test)]
mod tests {
    use super::encode::changes;
    use super::*;
    use crate::viz::palette::UNCHANGED;
    use draw::scale_bar;

    #[test]
    fn layout_scales_the_paper_map_and_makes_room_for_circles() {
        let pitch = 25.4 / 7.0;
        let l = FrameLayout::new(56, 147, 7, pitch, &[]);
        assert_eq!(l.scale, 4);
        assert_eq!(l.width, 147 * 4 + 2 * LABEL_PX + COLOUR_BAR_ROOM_PX);
        assert_eq!(l.map_origin, (LABEL_PX, TITLE_PX + LABEL_PX));
        assert_eq!(l.pixel_centre(0, 0), (16 + 2, 60 + 2));
        // Sensor cell (1, 2) is 7 x 7 map pixels of 4 x 4 image px.
        assert_eq!(l.cell_rect(1, 2), (16 + 56, 60 + 28, 16 + 84, 60 + 56));
        // The colour bar spans the map's height, right of its margin.
        let (x0, y0, _, y1) = l.colour_bar;
        assert!(x0 > 16 + 588 + LABEL_PX);
        assert_eq!((y0, y1), (60, 60 + 224));
        // A circle 10 mm past the top edge: the margin grows by its 11 px.
        let c = Circle {
            x_mm: 100.0,
            y_mm: 8.5,
            r_mm: 18.5,
            weight: 1.0,
        };
        let m = FrameLayout::new(56, 147, 7, pitch, &[c]);
        let over = (10.0 * 4.0 / pitch).ceil() as u32;
        assert_eq!(m.map_origin.1, TITLE_PX + over + LABEL_PX);
        assert_eq!(m.height, l.height + 2 * over);
    }

    #[test]
    fn scale_bar_is_a_round_length_that_fits() {
        // 4 px per 3.63 mm: at most 147 px = 133 mm, so 100 mm = 110 px.
        let px_per_mm = 4.0 / (25.4 / 7.0);
        let (mm, px) = scale_bar(px_per_mm, 147.0).unwrap();
        assert_eq!(mm, 100.0);
        assert_eq!(px, (100.0 * px_per_mm).round() as i32);
        assert_eq!(scale_bar(1.0, 49.0).unwrap().0, 20.0);
        assert_eq!(scale_bar(1.0, 50.0).unwrap().0, 50.0);
        assert_eq!(scale_bar(1.0, 0.5), None);
    }

    #[test]
    fn a_changed_rectangle_keeps_unchanged_pixels_transparent() {
        let before = vec![1u8; 5 * 4];
        let mut now = before.clone();
        now[5 + 1] = 2; // (1, 1)
        now[2 * 5 + 3] = 3; // (3, 2)
        let f = changes(&before, &now, 5);
        assert_eq!((f.left, f.top, f.width, f.height), (1, 1, 3, 2));
        let u = UNCHANGED;
        assert_eq!(&f.buffer[..], &[2, u, u, u, u, 3]);
        let same = changes(&before, &before, 5);
        assert_eq!((same.width, same.height), (1, 1));
        assert_eq!(&same.buffer[..], &[u]);
    }
}
