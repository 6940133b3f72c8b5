//! The preview's files: the GIF (one palette, only the changed rectangle after the
//! first frame) and a single PNG frame.

use std::borrow::Cow;

use touchc_input::recording::Recording;
use touchc_pipeline::compile::Compiled;

use super::{
    draw_frame, FrameLayout, PreviewError, Scene, ACTIVE, BOX, CURSOR, IDLE, OTHER, SPARK_AHEAD,
    SPARK_PAST, TRAJECTORY_COLOURS, UNEXPLAINED,
};
use crate::viz::palette::{Palette, UNCHANGED};
use crate::viz::plot::encode_png;
use crate::viz::{register_font, VizError};

/// The animation of `compiled` (run on `recording` without the crop): one GIF frame per
/// recording frame (every `every`-th, at least 1), played at the recording's rate,
/// looping.
pub fn gif(
    compiled: &Compiled,
    recording: &Recording,
    every: usize,
    frame_rate_hz: f64,
) -> Result<Vec<u8>, PreviewError> {
    register_font()?;
    let scene = Scene::new(compiled, recording)?;
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
        UNEXPLAINED,
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
        let mut shown: Option<Vec<u8>> = None;
        for t in (0..scene.count()).step_by(every) {
            draw_frame(&scene, t, frame_rate_hz, &mut rgb)?;
            let now = palette.indices(&rgb);
            let mut frame = match &shown {
                Some(before) => changes(before, &now, w16),
                None => gif::Frame {
                    width: w16,
                    height: h16,
                    buffer: Cow::Borrowed(&now[..]),
                    ..gif::Frame::default()
                },
            };
            frame.delay = delay;
            frame.dispose = gif::DisposalMethod::Keep;
            frame.transparent = Some(UNCHANGED);
            enc.write_frame(&frame).map_err(encode)?;
            drop(frame);
            shown = Some(now);
        }
    }
    Ok(out)
}

/// The GIF frame that turns `before` into `now` (palette indices, `width` px per row):
/// the smallest rectangle holding every changed pixel, with the unchanged ones inside
/// it [`UNCHANGED`] (transparent), which compresses to almost nothing. A frame where
/// nothing changed is one transparent pixel, so it still takes its time.
pub(super) fn changes<'f>(before: &[u8], now: &[u8], width: u16) -> gif::Frame<'f> {
    let w = usize::from(width);
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (i, _) in before
        .iter()
        .zip(now)
        .enumerate()
        .filter(|(_, (a, b))| a != b)
    {
        let (x, y) = (i % w, i / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    if x0 == usize::MAX {
        return gif::Frame {
            width: 1,
            height: 1,
            buffer: Cow::Owned(vec![UNCHANGED]),
            ..gif::Frame::default()
        };
    }
    let mut buffer = Vec::with_capacity((x1 - x0) * (y1 - y0));
    for y in y0..y1 {
        let row = y * w;
        buffer.extend(
            before[row + x0..row + x1]
                .iter()
                .zip(&now[row + x0..row + x1])
                .map(|(&a, &b)| if a == b { UNCHANGED } else { b }),
        );
    }
    // The rectangle lies inside a `width` x `height` image, so every side fits in u16.
    let side = |v: usize| u16::try_from(v).unwrap_or(u16::MAX);
    gif::Frame {
        left: side(x0),
        top: side(y0),
        width: side(x1 - x0),
        height: side(y1 - y0),
        buffer: Cow::Owned(buffer),
        ..gif::Frame::default()
    }
}

/// One frame of `compiled` (run on `recording` without the crop) as a PNG, to look at a
/// moment closely.
pub fn png_frame(
    compiled: &Compiled,
    recording: &Recording,
    t: usize,
    frame_rate_hz: f64,
) -> Result<Vec<u8>, PreviewError> {
    register_font()?;
    let scene = Scene::new(compiled, recording)?;
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

pub(super) fn too_big(width: u32, height: u32) -> VizError {
    VizError::Size {
        width,
        height,
        min: 1,
        max: u32::from(u16::MAX),
    }
}
