//! Text on the bitmap pictures, set with the bundled font's advances, kerning and side
//! bearings: plotters' own path for bitmaps places each glyph's ink box at a truncated
//! pen position, so the gaps between letters vary ("tou ch", "0.11 3 psi").
//!
//! The anchors are plotters' ([`Pos`]) and so are the vertical metrics (the baseline
//! half the font size below a top anchor), so a string lands where plotters' `Text`
//! put it, only evenly set.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::FONT;

/// The bundled font, parsed once.
fn font() -> Option<&'static FontRef<'static>> {
    static PARSED: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    PARSED
        .get_or_init(|| FontRef::try_from_slice(FONT).ok())
        .as_ref()
}

/// The pen positions of `text`'s glyphs at `size` px from x = 0, and the advance of
/// the whole string, px.
pub fn layout(text: &str, size: f64) -> (Vec<(ab_glyph::GlyphId, f32)>, f32) {
    let Some(font) = font() else {
        return (Vec::new(), 0.0);
    };
    let scaled = font.as_scaled(PxScale::from(size as f32));
    let mut pen = 0.0f32;
    let mut prev = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            pen += scaled.kern(p, id);
        }
        glyphs.push((id, pen));
        pen += scaled.h_advance(id);
        prev = Some(id);
    }
    (glyphs, pen)
}

/// Draws `text` at `at` (anchored as `pos`) in `colour`, `size` px high, each pixel
/// blended by the glyph's coverage.
pub fn draw<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    at: (i32, i32),
    size: f64,
    colour: RGBColor,
    pos: Pos,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let Some(font) = font() else {
        return Ok(());
    };
    let scale = PxScale::from(size as f32);
    let (glyphs, width) = layout(text, size);
    let x0 = at.0 as f32
        - match pos.h_pos {
            HPos::Left => 0.0,
            HPos::Center => width / 2.0,
            HPos::Right => width,
        };
    // plotters' box is `size / 1.24` high, and its top anchor puts the baseline half
    // the size below the anchor.
    let height = (size / 1.24).floor() as f32;
    let baseline = at.1 as f32 + (size / 2.0) as f32
        - match pos.v_pos {
            VPos::Top => 0.0,
            VPos::Center => (height / 2.0).floor(),
            VPos::Bottom => height,
        };
    for (id, pen) in glyphs {
        let glyph = id.with_scale_and_position(scale, ab_glyph::point(x0 + pen, baseline));
        let Some(outline) = font.outline_glyph(glyph) else {
            continue; // a space
        };
        let b = outline.px_bounds();
        let mut pixels = Vec::new();
        outline.draw(|x, y, coverage| {
            if coverage > 0.0 {
                pixels.push((
                    b.min.x as i32 + x as i32,
                    b.min.y as i32 + y as i32,
                    coverage,
                ));
            }
        });
        for (x, y, coverage) in pixels {
            area.draw_pixel((x, y), &colour.mix(f64::from(coverage.min(1.0))))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The horizontal centres of the ink runs (columns with any dark pixel) of a
    /// `w x h` RGB buffer.
    fn ink_centres(rgb: &[u8], w: usize, h: usize) -> Vec<f64> {
        let inked = |x: usize| (0..h).any(|y| rgb[3 * (y * w + x)] < 128);
        let mut centres = Vec::new();
        let mut start = None;
        for x in 0..=w {
            match (x < w && inked(x), start) {
                (true, None) => start = Some(x),
                (false, Some(s)) => {
                    centres.push((s + x - 1) as f64 / 2.0);
                    start = None;
                }
                _ => {}
            }
        }
        centres
    }

    /// Digits and spaces: each digit's advance plus a space's is the same, so the digits'
    /// centres are evenly spaced, and the spaces keep their ink apart at any size.
    const DIGITS: &str = "1 1 3 1 1 3 1";

    /// Spread (largest minus smallest) of the steps between the ink centres of
    /// [`DIGITS`] drawn by `f`.
    fn digit_step_spread(f: impl Fn(&DrawingArea<BitMapBackend<'_>, Shift>)) -> f64 {
        let (w, h) = (400usize, 60usize);
        let mut rgb = vec![255u8; w * h * 3];
        {
            let root =
                BitMapBackend::with_buffer(&mut rgb, (w as u32, h as u32)).into_drawing_area();
            f(&root);
            root.present().unwrap();
        }
        let c = ink_centres(&rgb, w, h);
        assert_eq!(c.len(), 7, "{c:?}");
        let steps: Vec<f64> = c.windows(2).map(|p| p[1] - p[0]).collect();
        let (lo, hi) = steps
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &s| (a.min(s), b.max(s)));
        hi - lo
    }

    /// DejaVu's digits share one advance, and each is centred in it: set right, their
    /// ink centres are evenly spaced (to a pixel's rounding). plotters' own bitmap text
    /// places each glyph's ink box at a truncated pen position, ignoring its side
    /// bearing, and at the preview's sizes a glyph lands up to 3 px off: the gaps of
    /// "0.11 3 psi".
    #[test]
    fn digits_are_evenly_spaced() {
        crate::viz::register_font().unwrap();
        for size in [10u32, 12, 13, 16, 40] {
            let ours = digit_step_spread(|root| {
                let top = Pos::new(HPos::Left, VPos::Top);
                draw(root, DIGITS, (10, 10), f64::from(size), BLACK, top).unwrap();
            });
            assert!(ours <= 1.0, "{size} px: steps vary by {ours} px");
        }
        // The measure sees the preview's old text: plotters' path at its 13 px.
        let plotters = digit_step_spread(|root| {
            let font = (crate::viz::FAMILY, 13).into_font().color(&BLACK);
            root.draw(&Text::new(DIGITS, (10, 10), font)).unwrap();
        });
        assert!(plotters >= 2.0, "plotters' steps vary by {plotters} px");
    }
}
