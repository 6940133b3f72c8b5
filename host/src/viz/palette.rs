//! The preview's colours: the heat scale of the pressure maps and the fixed 256-colour
//! GIF palette.
//!
//! One global palette for every frame (the heat scale, greys, the overlay colours, a
//! coarse cube for blended edges, and one transparent entry), looked up through a
//! 32 x 32 x 32 nearest-colour table: deterministic and fast, where per-frame
//! quantisation would make the colours flicker from frame to frame. The transparent
//! entry lets a GIF frame leave the pixels that did not change to the frame before.

use plotters::style::RGBColor;

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

/// The palette index no colour maps to: GIF frames mark "unchanged since the frame
/// before" with it.
pub(crate) const UNCHANGED: u8 = 255;

/// The exponent between a value's share of the scale and its place on the ramp: a
/// square root, so that touch at a fifth of the recording's peak (a light stroke beside
/// a firm press, the blurred edge of a contact) is a clear magenta, not near black, while
/// 0 stays black and the maximum pale.
pub const HEAT_GAMMA: f64 = 0.5;

/// The heat-scale colour of `x` in `[0, 1]` (clamped; NaN is 0), through
/// [`HEAT_GAMMA`]: public so that a test or a script can check a picture's colour bar
/// against the scale itself.
pub fn heat(x: f64) -> [u8; 3] {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0).powf(HEAT_GAMMA)
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

/// The fixed GIF palette and its nearest-colour table.
pub(crate) struct Palette {
    /// 256 RGB triples, flat.
    pub(crate) rgb: Vec<u8>,
    /// Palette index per 5-bit-per-channel colour.
    table: Vec<u8>,
}

impl Palette {
    /// The heat scale, 17 greys, `overlays` exactly, a coarse colour cube for blends
    /// (text edges on the map), 255 colours in all, and [`UNCHANGED`] last.
    pub(crate) fn new(overlays: &[RGBColor]) -> Palette {
        let mut colours: Vec<[u8; 3]> = (0..HEAT_LEVELS)
            .map(|i| heat(i as f64 / (HEAT_LEVELS - 1) as f64))
            .collect();
        colours.extend((0..=16).map(|i| [(i * 255 / 16) as u8; 3]));
        colours.extend(
            overlays
                .iter()
                .take(usize::from(UNCHANGED) - colours.len())
                .map(|c| [c.0, c.1, c.2]),
        );
        'cube: for r in [0u8, 128, 255] {
            for g in [0u8, 128, 255] {
                for b in [0u8, 128, 255] {
                    if colours.len() == usize::from(UNCHANGED) {
                        break 'cube;
                    }
                    colours.push([r, g, b]);
                }
            }
        }
        colours.resize(usize::from(UNCHANGED), [0, 0, 0]);
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
        // Black in the file; what shows through is the frame before.
        colours.push([0, 0, 0]);
        Palette {
            rgb: colours.concat(),
            table,
        }
    }

    /// The palette index of every pixel of an RGB8 buffer.
    pub(crate) fn indices(&self, rgb: &[u8]) -> Vec<u8> {
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
        let overlays = [
            RGBColor(0, 255, 0),
            RGBColor(255, 0, 255),
            RGBColor(31, 119, 180),
        ];
        let p = Palette::new(&overlays);
        assert_eq!(p.rgb.len(), 768);
        // No colour maps to the transparent entry, not even its own black.
        assert!((0..32 * 32 * 32).all(|i| p.table[i] != UNCHANGED));
        for c in overlays
            .iter()
            .chain([&RGBColor(0, 0, 0), &RGBColor(255, 255, 255)])
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
}
