//! `touchc sleeve list` and `touchc sleeve info`: which ports may be a sleeve, and
//! what one holds.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use serde_json::json;
use touch_protocol::link::BankState;
use touchc_link::serial;
use touchc_link::{DeviceInfo, SlotEntry};

use super::{connect, describe, open, running_twin, USB_IDS};
use crate::cli::report::escaped;

pub(super) fn list(probe: bool) -> anyhow::Result<()> {
    let mut found = serial::candidates(USB_IDS).context("cannot list the serial ports")?;
    if let Some(twin) = running_twin() {
        found.push(serial::Candidate {
            path: twin,
            usb: None,
            product: None,
            serial: None,
            is_sleeve: true,
        });
    }
    if found.is_empty() {
        // An empty list is an answer, not a failure.
        eprintln!(
            "touchc: no USB serial port found (to try the sleeve without hardware: \
             `bash firmware/twin/run.sh serve` in the workspace, then `touchc sleeve info`)"
        );
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    for c in &found {
        let mut line = identity(c);
        if probe {
            match open(&c.path).and_then(|mut s| Ok(s.info()?)) {
                Ok(i) => line.push_str(&format!(
                    "  firmware {}, layout {}",
                    escaped(&i.firmware),
                    escaped(&i.layout)
                )),
                Err(_) => line.push_str("  (no sleeve answered)"),
            }
        }
        writeln!(out, "{line}")?;
    }
    Ok(())
}

/// A port's line in `sleeve list`: its path, what it is, its USB ids, product and
/// serial number.
fn identity(c: &serial::Candidate) -> String {
    let Some((vid, pid)) = c.usb else {
        return format!("{}  sleeve twin (firmware/twin serve)", c.path.display());
    };
    let kind = if c.is_sleeve {
        "sleeve (USB)"
    } else {
        "USB-serial adapter"
    };
    let mut line = format!("{}  {kind}  {vid:04x}:{pid:04x}", c.path.display());
    if let Some(p) = &c.product {
        line.push_str(&format!("  {}", escaped(p)));
    }
    if let Some(s) = &c.serial {
        line.push_str(&format!("  serial {}", escaped(s)));
    }
    line
}

pub(super) fn info(port: Option<&Path>, as_json: bool) -> anyhow::Result<()> {
    let mut link = connect(port)?;
    let p = link.port.clone();
    let i = link.client.info().map_err(|e| describe(e, &p, "info"))?;
    let slots = match i.bank {
        BankState::Flashed(s) | BankState::Builtin(s) => s.slots,
        BankState::Refused { .. } => 0,
    };
    let mut entries = Vec::new();
    for slot in 0..slots {
        entries.push(
            link.client
                .slot(slot)
                .map_err(|e| describe(e, &p, "slot"))?,
        );
    }
    let mut out = std::io::stdout().lock();
    if as_json {
        writeln!(out, "{}", info_json(&p, &i, &entries))?;
        return Ok(());
    }
    info_text(&mut out, &p, &i, &entries)
}

/// The sleeve's info and slots as one JSON object.
fn info_json(p: &Path, i: &DeviceInfo, entries: &[SlotEntry]) -> serde_json::Value {
    let bank = match i.bank {
        BankState::Flashed(s) => {
            json!({"state": "flashed", "bytes": s.len, "slots": s.slots})
        }
        BankState::Builtin(s) => {
            json!({"state": "builtin", "bytes": s.len, "slots": s.slots})
        }
        BankState::Refused { blinks } => json!({"state": "refused", "led_code": blinks}),
    };
    json!({
        "port": p.display().to_string(),
        "link_version": i.link_version,
        "firmware": i.firmware,
        "layout": i.layout,
        "layout_hash": format!("{:08x}", i.layout_hash),
        "full_scale_ma": i.full_scale_ma,
        "limits": {
            "peak_ma": i.limits.peak_ma,
            "slew_ma_per_ms": i.limits.slew_ma_per_ms,
            "continuous_ma": i.limits.continuous_ma,
            "i2t_budget_ma2s": i.limits.i2t_budget_ma2s,
        },
        "bank_capacity": i.bank_capacity,
        "bank": bank,
        "slots": entries.iter().map(|s| json!({
            "slot": s.slot, "name": s.name, "duration_ms": s.duration_ms,
            "playback_ms": s.playback_ms, "playable": s.playable,
        })).collect::<Vec<_>>(),
    })
}

/// The sleeve's info and slots in words, one fact a line.
fn info_text(
    out: &mut impl Write,
    p: &Path,
    i: &DeviceInfo,
    entries: &[SlotEntry],
) -> anyhow::Result<()> {
    writeln!(out, "port:      {}", p.display())?;
    writeln!(
        out,
        "firmware:  {} (link version {})",
        escaped(&i.firmware),
        i.link_version
    )?;
    writeln!(
        out,
        "layout:    {} ({:08x})",
        escaped(&i.layout),
        i.layout_hash
    )?;
    let l = i.limits;
    writeln!(
        out,
        "limits:    peak {} mA, slew {} mA/ms, continuous {} mA, I2t budget {} A2s; full scale {} mA",
        l.peak_ma,
        l.slew_ma_per_ms,
        l.continuous_ma,
        f64::from(l.i2t_budget_ma2s) / 1e6,
        i.full_scale_ma
    )?;
    match i.bank {
        BankState::Flashed(s) => writeln!(
            out,
            "bank:      flashed, {} slots, {} of {} bytes",
            s.slots, s.len, i.bank_capacity
        )?,
        BankState::Builtin(s) => writeln!(
            out,
            "bank:      built in (the bank region is erased), {} slots",
            s.slots
        )?,
        BankState::Refused { blinks } => writeln!(
            out,
            "bank:      refused (LED code {blinks}); nothing plays until a good bank is uploaded"
        )?,
    }
    for s in entries {
        writeln!(
            out,
            "  slot {:>2}: {:<16} {:>7.3} s{}",
            s.slot,
            escaped(&s.name),
            f64::from(s.playback_ms) / 1000.0,
            if s.playable {
                ""
            } else {
                "  (another layout: never played)"
            }
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sleeve_is_listed_with_its_usb_identity() {
        let c = serial::Candidate {
            path: "/dev/ttyACM0".into(),
            usb: Some((0x1209, 0x0001)),
            product: Some("touchc sleeve".into()),
            serial: Some("303132333435363738393A3B".into()),
            is_sleeve: true,
        };
        assert_eq!(
            identity(&c),
            "/dev/ttyACM0  sleeve (USB)  1209:0001  touchc sleeve  serial 303132333435363738393A3B"
        );
        let adapter = serial::Candidate {
            path: "/dev/ttyUSB0".into(),
            usb: Some((0x0403, 0x6001)),
            product: None,
            serial: None,
            is_sleeve: false,
        };
        assert_eq!(
            identity(&adapter),
            "/dev/ttyUSB0  USB-serial adapter  0403:6001"
        );
    }
}
