//! Seeing and feeling a stimulus without the sleeve: plots of the player's output
//! ([`plot`]), a multichannel WAV of the drive signal ([`wav`]), and an animated
//! preview of how a recording becomes actuator intensities ([`preview`]).
//!
//! Plots and WAVs start from what the sleeve would output, not from the compiler's
//! floating-point signals: [`play`] runs the protocol crate's fixed-point [`Player`],
//! the code the firmware runs, so limits, ramps and quantisation show as they will
//! be felt.

pub mod palette;
pub mod plot;
pub mod preview;
pub mod text;
pub mod trade;
pub mod wav;

use std::sync::OnceLock;

use touch_protocol::player::{code_to_amps, Fault};
use touch_protocol::{DeviceConfig, Player, Status, Stimulus, CHANNELS};

use touchc_rendering::condition::OUTPUT_RATE_HZ;

/// Why a picture or sound could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VizError {
    /// The bundled font was refused by the text renderer (a build defect, not user data).
    #[error("the bundled font cannot be loaded")]
    Font,
    /// The drawing library failed (e.g. a size too small to lay out the panels).
    #[error("drawing failed: {0}")]
    Draw(String),
    /// The image encoder failed.
    #[error("encoding the image failed: {0}")]
    Encode(String),
    /// The requested image size is unusable.
    #[error("image size {width} x {height} px is outside {min} ..= {max} px per side")]
    Size {
        /// Requested width, px.
        width: u32,
        /// Requested height, px.
        height: u32,
        /// Smallest side allowed, px.
        min: u32,
        /// Largest side allowed, px.
        max: u32,
    },
}

/// DejaVu Sans (Bitstream Vera licence, `host/assets/fonts/DejaVuSans.LICENSE`): bundled
/// so that text renders the same everywhere without the system's fontconfig.
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family name plots and previews ask for; [`register_font`] binds it to [`FONT`].
pub(crate) const FAMILY: &str = "sans-serif";

/// Registers the bundled font with plotters once per process; every drawing calls this
/// first, since plotters draws no text at all (and SVG output fails) without a font.
pub(crate) fn register_font() -> Result<(), VizError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        plotters::style::register_font(FAMILY, plotters::style::FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(VizError::Font)
    }
}

/// The sleeve's output for one stimulus, tick by tick (1 kHz), as the firmware would
/// emit it, through the ramp down to the first idle tick. An iterator, so that a
/// stimulus of any length is rendered, plotted or resampled in constant memory.
pub struct Ticks<'a> {
    player: Player<'a>,
    device: DeviceConfig,
    t: usize,
    fault: Option<(usize, Fault)>,
}

impl Ticks<'_> {
    /// The first limit hit so far, and the tick it happened at; the player ramped down
    /// from there.
    pub fn fault(&self) -> Option<(usize, Fault)> {
        self.fault
    }

    /// The device the codes are for.
    pub fn device(&self) -> &DeviceConfig {
        &self.device
    }

    /// A code's current on this device, amperes.
    pub fn amps(&self, code: u16) -> f64 {
        code_to_amps(code, self.device.full_scale_ma)
    }
}

impl Iterator for Ticks<'_> {
    /// Output codes of one tick, channel order (2048 = 0 A).
    type Item = [u16; CHANNELS];

    fn next(&mut self) -> Option<Self::Item> {
        let tick = self.player.next()?;
        if let Status::Fault(f) = tick.status {
            self.fault.get_or_insert((self.t, f));
        }
        self.t += 1;
        Some(tick.codes)
    }
}

/// Plays `stimulus` on `device` to the end, exactly as the firmware would.
pub fn play<'a>(stimulus: &Stimulus<'a>, device: &DeviceConfig) -> Ticks<'a> {
    Ticks {
        player: Player::new(stimulus, device),
        device: *device,
        t: 0,
        fault: None,
    }
}

/// Says which limit stopped the player and when, for warnings and plot titles.
pub fn describe_fault((t, f): (usize, Fault)) -> String {
    format!(
        "{:?} limit hit on channel {} at {:.3} s; the player ramped to 0 A",
        f.kind,
        f.channel,
        t as f64 / OUTPUT_RATE_HZ
    )
}
