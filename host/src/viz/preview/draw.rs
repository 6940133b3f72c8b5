//! What the preview draws on each frame besides the pressure map: the unexplained
//! touch, the overlay of trajectories and workspaces, the colour bar, the arm's
//! orientation, the legend and the actuator panel.

use ndarray::Axis;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use touch_protocol::CHANNELS;
use touchc_pipeline::coverage::{Cell, DEFAULT_RADIUS_CELLS};
use touchc_rendering::signals::Source;

use super::{
    rgb_of, Canvas, FrameLayout, Scene, ACTIVE, BAR_PX, BOX, BOX_PX, CURSOR, IDLE, LEGEND_ROWS,
    LEGEND_ROW_PX, OTHER, OUTLINE_PX, PAD_PX, SPARK_AHEAD, SPARK_PAST, TRAIL_FRAMES,
    TRAJECTORY_COLOURS, UNEXPLAINED,
};
use crate::viz::palette::heat;

/// Hatches every unexplained sensor cell of one frame and outlines each unexplained
/// region (an edge is drawn where the neighbouring cell is not unexplained), so a
/// missed patch reads as one shape, however many cells it spans.
pub(super) fn mark_unexplained(
    canvas: &mut Canvas<'_>,
    l: &FrameLayout,
    cells: ndarray::ArrayView2<Cell>,
) {
    let (rows, cols) = cells.dim();
    let red = rgb_of(UNEXPLAINED);
    let missed = |r: usize, c: usize| cells[[r, c]] == Cell::Unexplained;
    for ((r, c), _) in cells
        .indexed_iter()
        .filter(|&(_, &v)| v == Cell::Unexplained)
    {
        let rect @ (x0, y0, x1, y1) = l.cell_rect(r, c);
        canvas.hatch(rect, red);
        let w = OUTLINE_PX;
        if r == 0 || !missed(r - 1, c) {
            canvas.fill((x0, y0, x1, y0 + w), red);
        }
        if r + 1 == rows || !missed(r + 1, c) {
            canvas.fill((x0, y1 - w, x1, y1), red);
        }
        if c == 0 || !missed(r, c - 1) {
            canvas.fill((x0, y0, x0 + w, y1), red);
        }
        if c + 1 == cols || !missed(r, c + 1) {
            canvas.fill((x1 - w, y0, x1, y1), red);
        }
    }
}

/// The legend's dark band, `(x0, y0, x1, y1)`.
pub(super) fn legend_band(l: &FrameLayout) -> (usize, usize, usize, usize) {
    (
        PAD_PX as usize,
        l.legend_top as usize,
        (l.width - PAD_PX) as usize,
        (l.legend_top + LEGEND_ROWS * LEGEND_ROW_PX) as usize,
    )
}

/// The marker swatch of legend entry `k` (row-major, two per row), `(x0, y0, x1, y1)`.
pub(super) fn swatch_rect(l: &FrameLayout, k: u32) -> (usize, usize, usize, usize) {
    let col_w = (l.width - 2 * PAD_PX) / 2;
    let x0 = PAD_PX + 6 + (k % 2) * col_w;
    let y0 = l.legend_top + (k / 2) * LEGEND_ROW_PX + 3;
    (
        x0 as usize,
        y0 as usize,
        (x0 + 30) as usize,
        (y0 + LEGEND_ROW_PX - 6) as usize,
    )
}

/// The longest "round" length (1, 2 or 5 times a power of ten, in mm) that is at most
/// `max_px` long at `px_per_mm`, and its length in px; `None` when not even 1 mm fits.
pub(super) fn scale_bar(px_per_mm: f64, max_px: f64) -> Option<(f64, i32)> {
    let max_mm = max_px / px_per_mm;
    // NaN (no scale) fails this too.
    if max_mm.is_nan() || max_mm < 1.0 {
        return None;
    }
    let decade = 10f64.powf(max_mm.log10().floor());
    let mm = [5.0, 2.0, 1.0]
        .iter()
        .map(|m| m * decade)
        .find(|&mm| mm <= max_mm)
        .unwrap_or(decade);
    Some((mm, (mm * px_per_mm).round() as i32))
}

/// plotters' default text anchor.
const TOP_LEFT: Pos = Pos {
    h_pos: HPos::Left,
    v_pos: VPos::Top,
};

/// `text` at `at`, evenly set (see [`crate::viz::text`]).
fn label<'b>(
    root: &Area<'b>,
    text: &str,
    at: (i32, i32),
    size: f64,
    colour: RGBColor,
    pos: Pos,
) -> DrawResult<'b> {
    crate::viz::text::draw(root, text, at, size, colour, pos)
}

pub(super) type Area<'b> = DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>;
pub(super) type DrawResult<'b> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'b> as DrawingBackend>::ErrorType>>;

pub(super) fn overlay<'b>(
    scene: &Scene<'_>,
    t: usize,
    rate_hz: f64,
    root: &Area<'b>,
) -> DrawResult<'b> {
    let l = scene.layout;
    let c = scene.compiled;
    let missed_now = scene
        .cells
        .index_axis(Axis(0), t)
        .iter()
        .filter(|&&v| v == Cell::Unexplained)
        .count();
    label(
        root,
        &format!(
            "{}  frame {}/{}  {:.2} s  unexplained touch now: {missed_now} cells",
            std::path::Path::new(&c.report.input)
                .file_name()
                .map_or(c.report.input.as_str(), |n| n.to_str().unwrap_or("")),
            t,
            scene.count(),
            t as f64 / rate_hz.max(1.0),
        ),
        (PAD_PX as i32, 4),
        16.0,
        BLACK,
        TOP_LEFT,
    )?;
    let cov = &scene.coverage;
    label(
        root,
        &format!(
            "coverage {:.0}%, played {:.0}%: touch more than {DEFAULT_RADIUS_CELLS} cells \
             from every contact is hatched red ({} of {} touch readings)",
            100.0 * cov.ratio(),
            100.0 * c.report.rendered_coverage,
            cov.unexplained_cells,
            cov.touch_cells
        ),
        (PAD_PX as i32, 24),
        13.0,
        BLACK,
        TOP_LEFT,
    )?;
    colour_bar_labels(scene, root)?;
    orientation(scene, root)?;
    legend(&l, rate_hz, root)?;
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
            label(
                root,
                &format!("{ch}"),
                (centre.0 - 4, centre.1 - radius - 14),
                12.0,
                IDLE,
                TOP_LEFT,
            )?;
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
                .points
                .iter()
                .filter(|p| p.frame <= t && p.frame + TRAIL_FRAMES > t)
                .map(|p| l.pixel_centre(p.row, p.col))
                .collect();
            if trail.len() > 1 {
                root.draw(&PathElement::new(trail.clone(), colour.stroke_width(2)))?;
            }
            if let Some(p) = traj.at_frame(t) {
                let at = l.pixel_centre(p.row, p.col);
                root.draw(&plotters::element::Circle::new(at, 5, colour.filled()))?;
            }
        }
    }
    actuator_panel(scene, t, rate_hz, root)
}

/// A value in its shortest form with at most two decimals (`0.77`, `0`, `6.7`).
fn short(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The colour bar's outline and its psi labels: the maximum at the top, 0 at the bottom,
/// the middle between.
pub(super) fn colour_bar_labels<'b>(scene: &Scene<'_>, root: &Area<'b>) -> DrawResult<'b> {
    let (x0, y0, x1, y1) = scene.layout.colour_bar;
    let (x0, y0, x1, y1) = (x0 as i32, y0 as i32, x1 as i32, y1 as i32);
    root.draw(&Rectangle::new(
        [(x0 - 1, y0 - 1), (x1, y1)],
        BOX.stroke_width(1),
    ))?;
    let left = Pos::new(HPos::Left, VPos::Center);
    for (frac, y) in [(1.0, y0), (0.5, (y0 + y1) / 2), (0.0, y1 - 1)] {
        root.draw(&PathElement::new(
            vec![(x1, y), (x1 + 4, y)],
            BLACK.stroke_width(1),
        ))?;
        label(
            root,
            &format!("{:.2}", frac * scene.vmax),
            (x1 + 6, y),
            12.0,
            BLACK,
            left,
        )?;
    }
    label(
        root,
        "psi",
        ((x0 + x1) / 2, y0 - 4),
        12.0,
        BLACK,
        Pos::new(HPos::Center, VPos::Bottom),
    )
}

/// Under the map: which end is the elbow and which the wrist (column 0 is nearest the
/// elbow), and a scale bar in mm.
pub(super) fn orientation<'b>(scene: &Scene<'_>, root: &Area<'b>) -> DrawResult<'b> {
    let l = scene.layout;
    let (x0, y) = (l.map_origin.0 as i32, (l.orient_top + 6) as i32);
    let x1 = x0 + (l.map_px.1 as u32 * l.scale) as i32;
    label(
        root,
        "\u{2190} elbow (sensor column 0)",
        (x0, y),
        13.0,
        BLACK,
        TOP_LEFT,
    )?;
    label(
        root,
        "wrist \u{2192}",
        (x1, y),
        13.0,
        BLACK,
        Pos::new(HPos::Right, VPos::Top),
    )?;
    let px_per_mm = f64::from(l.scale) / scene.pitch_mm;
    let Some((mm, len)) = scale_bar(px_per_mm, f64::from(x1 - x0) / 4.0) else {
        return Ok(());
    };
    let (mid, bar_y) = ((x0 + x1) / 2, y + 18);
    let (a, b) = (mid - len / 2, mid - len / 2 + len);
    root.draw(&Rectangle::new(
        [(a, bar_y - 1), (b, bar_y + 2)],
        BLACK.filled(),
    ))?;
    for x in [a, b - 1] {
        root.draw(&PathElement::new(
            vec![(x, bar_y - 5), (x, bar_y + 5)],
            BLACK.stroke_width(1),
        ))?;
    }
    label(
        root,
        &format!("{mm} mm"),
        (mid, bar_y - 4),
        12.0,
        BLACK,
        Pos::new(HPos::Center, VPos::Bottom),
    )
}

/// One legend entry per marker, two per row, white on the dark band.
pub(super) fn legend<'b>(l: &FrameLayout, rate_hz: f64, root: &Area<'b>) -> DrawResult<'b> {
    let trail_s = TRAIL_FRAMES as f64 / rate_hz.max(1.0);
    let entries = [
        format!("selected trajectory: trail of the last {trail_s:.1} s, dot = now"),
        "trajectory placement did not select".to_string(),
        "actuator workspace (channel number), actuator on".to_string(),
        "actuator workspace, actuator at rest".to_string(),
        format!("touch no contact explains (> {DEFAULT_RADIUS_CELLS} cells away)"),
        "heat: blurred pressure, colour bar in psi".to_string(),
        "actuator signal, psi: so far (blue), to come (grey)".to_string(),
        "red line: now; bar: the actuator's intensity now".to_string(),
    ];
    let font = Pos::new(HPos::Left, VPos::Center);
    for (k, text) in (0u32..).zip(&entries) {
        let (x0, y0, x1, y1) = swatch_rect(l, k);
        let (x0, y0, x1, y1) = (x0 as i32, y0 as i32, x1 as i32, y1 as i32);
        let ym = (y0 + y1) / 2;
        match k {
            0 | 1 => {
                let colour = if k == 0 { TRAJECTORY_COLOURS[0] } else { OTHER };
                root.draw(&PathElement::new(
                    vec![(x0, y1 - 2), (x0 + 10, ym + 2), (x1 - 6, ym)],
                    colour.stroke_width(2),
                ))?;
                root.draw(&plotters::element::Circle::new(
                    (x1 - 6, ym),
                    5,
                    colour.filled(),
                ))?;
            }
            2 | 3 => {
                let style = if k == 2 {
                    ACTIVE.stroke_width(3)
                } else {
                    IDLE.stroke_width(1)
                };
                root.draw(&plotters::element::Circle::new(
                    ((x0 + x1) / 2, ym),
                    (y1 - y0) / 2,
                    style,
                ))?;
            }
            4 => {
                // The hatching is in the buffer already (see `draw_frame`).
                root.draw(&Rectangle::new(
                    [(x0, y0), (x1 - 1, y1 - 1)],
                    UNEXPLAINED.stroke_width(2),
                ))?;
            }
            6 => {
                let wave = |i: i32| ym + 4 - ((f64::from(i) * 0.5).sin().abs() * 9.0) as i32;
                let mid = (x0 + x1) / 2;
                root.draw(&PathElement::new(
                    (x0..mid).map(|x| (x, wave(x - x0))).collect::<Vec<_>>(),
                    SPARK_PAST.stroke_width(1),
                ))?;
                root.draw(&PathElement::new(
                    (mid..x1).map(|x| (x, wave(x - x0))).collect::<Vec<_>>(),
                    SPARK_AHEAD.stroke_width(1),
                ))?;
            }
            7 => {
                root.draw(&PathElement::new(
                    vec![(x0 + 6, y0), (x0 + 6, y1 - 1)],
                    CURSOR.stroke_width(1),
                ))?;
                let [r, g, b] = heat(0.8);
                let bar = (x1 - 6 - BAR_PX, x1 - 6);
                root.draw(&Rectangle::new(
                    [(bar.0, ym - 2), (bar.1, y1 - 1)],
                    RGBColor(r, g, b).filled(),
                ))?;
                root.draw(&Rectangle::new(
                    [(bar.0, y0), (bar.1, y1 - 1)],
                    BOX.stroke_width(1),
                ))?;
            }
            _ => {
                for i in 0..(x1 - x0) {
                    let [r, g, b] = heat(f64::from(i) / f64::from(x1 - x0 - 1));
                    root.draw(&PathElement::new(
                        vec![(x0 + i, y0), (x0 + i, y1 - 1)],
                        RGBColor(r, g, b).stroke_width(1),
                    ))?;
                }
            }
        }
        label(root, text, (x1 + 8, ym), 12.0, IDLE, font)?;
    }
    Ok(())
}

/// Where actuator `ch`'s box sits: its top-left corner and width, px.
pub(super) fn actuator_box(l: &FrameLayout, ch: usize) -> (i32, i32, i32) {
    let top = (l.height - 2 * BOX_PX - PAD_PX) as i32;
    let box_w = ((l.width - 2 * PAD_PX) / 4) as i32;
    let (row, col) = ((ch / 4) as i32, (ch % 4) as i32);
    (
        PAD_PX as i32 + col * box_w,
        top + row * BOX_PX as i32,
        box_w,
    )
}

/// Room left of a signal trace for its psi labels, px.
const STRIP_AXIS_PX: i32 = 30;

/// The pixel rectangle `(x0, y0, x1, y1)` of actuator `ch`'s signal trace.
pub(super) fn trace_rect(l: &FrameLayout, ch: usize) -> (i32, i32, i32, i32) {
    let (x0, y0, w) = actuator_box(l, ch);
    (
        x0 + STRIP_AXIS_PX,
        y0 + 20,
        x0 + w - BAR_PX - 10,
        y0 + BOX_PX as i32 - 8,
    )
}

/// Each channel's whole pressure signal as trace points, one per pixel column (the
/// column's largest value), so a frame draws a few hundred segments, not thousands.
pub(super) fn traces(
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
pub(super) fn column(x0: i32, x1: i32, t: usize, n: usize) -> i32 {
    x0 + ((x1 - x0) as f64 * t as f64 / n.saturating_sub(1).max(1) as f64).round() as i32
}

/// The eight actuators in the sleeve's layout: what each renders now (value, source,
/// a heat-coloured bar) and its whole signal with a cursor at this frame.
pub(super) fn actuator_panel<'b>(
    scene: &Scene<'_>,
    t: usize,
    rate_hz: f64,
    root: &Area<'b>,
) -> DrawResult<'b> {
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
        label(
            root,
            &format!("ch{ch}: {psi:.3} psi{why}"),
            (x0 + 6, y0 + 4),
            12.0,
            BLACK,
            TOP_LEFT,
        )?;
        // The axes: psi from 0 to the largest of any channel up the left, time from
        // the first frame to the last along the bottom (its end labelled at the right).
        let (tx0, ty0, tx1, ty1) = trace_rect(l, ch);
        root.draw(&PathElement::new(
            vec![(tx0 - 1, ty0), (tx0 - 1, ty1), (tx1, ty1)],
            BOX.stroke_width(1),
        ))?;
        let right = Pos::new(HPos::Right, VPos::Center);
        for (y, v) in [(ty0, scene.psi_max), (ty1, 0.0)] {
            root.draw(&PathElement::new(
                vec![(tx0 - 4, y), (tx0 - 1, y)],
                BOX.stroke_width(1),
            ))?;
            label(root, &short(v), (tx0 - 5, y), 10.0, BLACK, right)?;
        }
        label(
            root,
            &format!("{} s", short(scene.count() as f64 / rate_hz.max(1.0))),
            (tx1, ty1 - 2),
            10.0,
            BLACK,
            Pos::new(HPos::Right, VPos::Bottom),
        )?;
        // The signal so far over the whole signal in grey, and a cursor at this frame.
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
