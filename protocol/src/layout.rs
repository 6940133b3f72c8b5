//! The actuator layout's identity: a hash of its geometry, not of its name.
//!
//! A stimulus drives eight channels; what each channel means on the arm is the
//! layout's geometry (which centre is channel 0, how far apart they sit, how large each
//! workspace is). Two layouts that differ there must never be mistaken for each other,
//! whatever they are called: a mirrored layout that kept the name `paper-2x4` would play
//! with its rows swapped. So a stimulus and a bank carry [`geometry_hash`] of the layout
//! they were compiled for, and the firmware and `touchc bank` compare hashes; the
//! layout's name travels beside it only so that a refusal can say which layouts met.
//!
//! The hash is the CRC-32 (the containers' CRC) of the canonical geometry bytes: for each
//! channel in channel order, its centre relative to channel 0's centre and its workspace
//! radius, each in whole micrometres as a little-endian `i32`. Relative centres make the
//! hash independent of where the layout's frame puts its origin (placement translates the
//! layout anyway); a micrometre is far below any sleeve's tolerance, so values written
//! with different decimal digits but the same geometry hash alike.

use crate::container;
use crate::CHANNELS;

/// Longest layout name a stimulus carries, bytes of UTF-8.
pub const MAX_NAME_LEN: usize = 24;

/// Bytes of the canonical geometry that [`geometry_hash`] covers: three `i32` per channel.
pub const CANONICAL_LEN: usize = CHANNELS * 12;

/// One actuator's place, in whole micrometres of the layout's own frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Actuator {
    /// Centre along the arm, µm (column 0 nearest the elbow).
    pub x_um: i32,
    /// Centre across the arm, µm.
    pub y_um: i32,
    /// Radius of the workspace the actuator renders, µm.
    pub radius_um: i32,
}

/// The canonical bytes of a geometry given in channel order (see the module docs).
pub const fn canonical_bytes(actuators: &[Actuator; CHANNELS]) -> [u8; CANONICAL_LEN] {
    let mut out = [0u8; CANONICAL_LEN];
    let (x0, y0) = (actuators[0].x_um, actuators[0].y_um);
    let mut c = 0;
    while c < CHANNELS {
        let a = actuators[c];
        let fields = [
            a.x_um.wrapping_sub(x0),
            a.y_um.wrapping_sub(y0),
            a.radius_um,
        ];
        let mut f = 0;
        while f < 3 {
            let b = fields[f].to_le_bytes();
            let at = c * 12 + f * 4;
            out[at] = b[0];
            out[at + 1] = b[1];
            out[at + 2] = b[2];
            out[at + 3] = b[3];
            f += 1;
        }
        c += 1;
    }
    out
}

/// The hash a stimulus and a bank carry for a layout with these actuators, in channel
/// order (one definition for the compiler, `touchc bank` and the firmware).
///
/// ```
/// use touch_protocol::layout::{geometry_hash, Actuator, SLEEVE, SLEEVE_HASH};
/// assert_eq!(geometry_hash(&SLEEVE), SLEEVE_HASH);
/// // The paper's sleeve with its rows swapped is another layout.
/// let mut mirrored = SLEEVE;
/// mirrored.rotate_left(4);
/// assert_ne!(geometry_hash(&mirrored), SLEEVE_HASH);
/// // Moving the whole layout is not.
/// let moved = SLEEVE.map(|a| Actuator { x_um: a.x_um + 5_000, ..a });
/// assert_eq!(geometry_hash(&moved), SLEEVE_HASH);
/// ```
pub const fn geometry_hash(actuators: &[Actuator; CHANNELS]) -> u32 {
    container::crc32_const(&canonical_bytes(actuators))
}

const fn paper(column: i32, row: i32) -> Actuator {
    Actuator {
        x_um: column * 37_000,
        y_um: row * 50_000,
        radius_um: 18_500,
    }
}

/// The sleeve this firmware drives: the paper's 2 x 4 voice coils, 37 mm apart along a
/// row and 50 mm between rows, workspaces of radius 18.5 mm, `channel = row * 4 +
/// column` (the host's `layouts/paper.toml`; a host test keeps the two equal).
pub const SLEEVE: [Actuator; CHANNELS] = [
    paper(0, 0),
    paper(1, 0),
    paper(2, 0),
    paper(3, 0),
    paper(0, 1),
    paper(1, 1),
    paper(2, 1),
    paper(3, 1),
];

/// The name of [`SLEEVE`]'s layout, as its layout file gives it.
pub const SLEEVE_NAME: &str = "paper-2x4";

/// [`geometry_hash`] of [`SLEEVE`].
pub const SLEEVE_HASH: u32 = geometry_hash(&SLEEVE);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_bytes_are_relative_micrometres_in_channel_order() {
        let bytes = canonical_bytes(&SLEEVE);
        // Channel 0 sits at the origin of its own frame.
        assert_eq!(&bytes[..8], &[0; 8]);
        assert_eq!(&bytes[8..12], &18_500i32.to_le_bytes());
        // Channel 5: column 1, row 1.
        assert_eq!(&bytes[60..64], &37_000i32.to_le_bytes());
        assert_eq!(&bytes[64..68], &50_000i32.to_le_bytes());
    }

    #[test]
    fn every_geometric_change_changes_the_hash() {
        let changes: [fn(&mut [Actuator; CHANNELS]); 4] = [
            |l| l.swap(0, 3),        // order: two channels exchanged
            |l| l.rotate_left(4),    // rows swapped
            |l| l[6].radius_um += 1, // one radius, by a micrometre
            |l| l[2].y_um -= 1,      // one centre, by a micrometre
        ];
        for change in changes {
            let mut l = SLEEVE;
            change(&mut l);
            assert_ne!(geometry_hash(&l), SLEEVE_HASH);
        }
    }

    #[test]
    fn the_sleeve_hash_is_pinned() {
        // A change of the canonical bytes is a change of the stimulus format: pinned,
        // to Python's `zlib.crc32` of `struct.pack('<iii', ...)` over the eight channels.
        assert_eq!(SLEEVE_HASH, 0x98d8_60ac, "{SLEEVE_HASH:#010x}");
    }
}
