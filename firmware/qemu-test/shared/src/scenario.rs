//! The button script both sides play through the firmware's engine: the host in the
//! build script, the target under QEMU. Times are 1 kHz ticks.

/// Ticks the scenario runs.
pub const TICKS: u32 = 4500;

/// The newest edge of the one button at tick `t` (`Some(pressed)`).
pub fn edge(t: u32) -> Option<bool> {
    match t {
        // A bouncy short press at power-up: plays slot 0 on release.
        0 | 3 => Some(true),
        2 | 80 => Some(false),
        // Short press while it plays: stop, ramping down.
        1000 => Some(true),
        1060 => Some(false),
        // Long press: select slot 1.
        1500 => Some(true),
        2300 => Some(false),
        // Short press: play slot 1, then stop it.
        2500 => Some(true),
        2560 => Some(false),
        3000 => Some(true),
        3050 => Some(false),
        _ => None,
    }
}
