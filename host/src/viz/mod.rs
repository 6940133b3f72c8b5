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
pub mod wav;

use std::sync::OnceLock;

use touch_protocol::player::{code_to_amps, Fault};
use touch_protocol::{DeviceConfig, Player, Status, Stimulus, CHANNELS};

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

/// The sleeve's output for one stimulus: every 1 kHz tick's codes, as the firmware
/// would emit them, through the ramp down to the first idle tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Playback {
    /// Output codes per tick, channel order (2048 = 0 A).
    pub codes: Vec<[u16; CHANNELS]>,
    /// The device the codes are for: its full scale turns codes into amperes.
    pub device: DeviceConfig,
    /// The first limit hit, and the tick it happened at; the player ramped down there.
    pub fault: Option<(usize, Fault)>,
}

impl Playback {
    /// Channel `ch`'s current at tick `t`, amperes.
    pub fn amps(&self, t: usize, ch: usize) -> f64 {
        code_to_amps(self.codes[t][ch], self.device.full_scale_ma)
    }

    /// Length in seconds (1 kHz ticks).
    pub fn seconds(&self) -> f64 {
        self.codes.len() as f64 / 1000.0
    }
}

/// Plays `stimulus` on `device` to the end, exactly as the firmware would.
pub fn play(stimulus: &Stimulus<'_>, device: &DeviceConfig) -> Playback {
    let mut fault = None;
    let codes = Player::new(stimulus, device)
        .enumerate()
        .map(|(t, tick)| {
            if let Status::Fault(f) = tick.status {
                fault.get_or_insert((t, f));
            }
            tick.codes
        })
        .collect();
    Playback {
        codes,
        device: *device,
        fault,
    }
}
