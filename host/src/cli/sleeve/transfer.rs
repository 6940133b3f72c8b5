//! `touchc sleeve upload` and `touchc sleeve stream`: stimuli onto the sleeve, as a
//! bank it keeps or a stream it plays as it arrives.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context};
use touch_protocol::link::{Event, LinkError, Source, StreamStop};
use touch_protocol::{bank, Stimulus};
use touchc_link::{ClientError, Progress};

use super::{bar, connect, describe, limit_name, open, Link, Sleeve};
use crate::cli::report::{escaped, usage};

/// The image to upload: a bank file as it is, or the stimuli packed into one.
fn image_of(files: &[PathBuf], layout: Option<&Path>) -> anyhow::Result<Vec<u8>> {
    if let [one] = files {
        let bytes = crate::cli::input::read_input(one)?;
        if bytes.starts_with(&bank::MAGIC) {
            if layout.is_some() {
                return Err(usage(
                    "--layout applies to stimuli; a bank image is uploaded as it is",
                ));
            }
            touch_protocol::Bank::decode(&bytes)
                .with_context(|| format!("{}: not a valid bank", one.display()))?;
            return Ok(bytes);
        }
    }
    for f in files {
        if f.extension().is_some_and(|e| e == "bank") && files.len() > 1 {
            return Err(usage(format!(
                "{}: upload takes one bank image, or stimuli to pack into one, not both",
                f.display()
            )));
        }
    }
    Ok(crate::cli::bank::build(files, layout, Path::new("the bank"))?.0)
}

pub(super) fn upload(
    port: Option<&Path>,
    files: &[PathBuf],
    layout: Option<&Path>,
) -> anyhow::Result<()> {
    let image = image_of(files, layout)?;
    let Link { port, mut client } = connect(port)?;
    let info = client.info().map_err(|e| describe(e, &port, "info"))?;
    // Checked here, before the sleeve erases its bank for an image it would refuse.
    let bank = touch_protocol::Bank::decode(&image).context("the bank does not decode")?;
    for (slot, s) in bank.stimuli().enumerate() {
        let name = if let [one] = files {
            one.display().to_string()
        } else {
            files
                .get(slot)
                .map_or_else(|| format!("slot {slot}"), |f| f.display().to_string())
        };
        same_layout(
            &s,
            &info,
            &format!("{name}: slot {slot} ({})", escaped(s.name())),
        )?;
    }
    if image.len() as u64 > u64::from(info.bank_capacity) {
        bail!(
            "the bank is {} bytes, the sleeve's bank region {} bytes",
            image.len(),
            info.bank_capacity
        );
    }
    let bar = bar(image.len() as u64, "bytes");
    bar.set_message("erasing");
    let uploaded = client.upload(&image, |p: Progress| bar.set_position(p.done));
    bar.finish_and_clear();
    let slots = match uploaded {
        Ok(slots) => slots,
        // A cut after the commit wrote the bank's head leaves the new bank in place
        // although its reply never came; anywhere else, the upload is lost.
        Err(ClientError::Restarted { .. }) => return after_restart(client, &port, &image),
        Err(e) => return Err(describe(e, &port, "upload")),
    };
    // The sleeve restarts into the new bank: asked again once it is back, on the same
    // port; a USB socket goes away and comes back, and is opened again.
    let mut client = match client.reconnect() {
        Ok(_) => client,
        Err(_) => {
            drop(client);
            reopen(&port)?
        }
    };
    verify(&mut client, &port, &image)?;
    eprintln!(
        "touchc: {}: uploaded and verified {} bytes, {} slots",
        port.display(),
        image.len(),
        slots
    );
    Ok(())
}

/// Reads the bank back and compares it with `image`.
fn verify(client: &mut Sleeve, port: &Path, image: &[u8]) -> anyhow::Result<()> {
    let bar = self::bar(image.len() as u64, "bytes read back");
    let verified = client
        .verify(image, |p: Progress| bar.set_position(p.done))
        .map_err(|e| describe(e, port, "verify"));
    bar.finish_and_clear();
    verified
}

/// The sleeve restarted before it answered the upload: says whether the new bank
/// is in place (read back whole) or the upload was lost.
fn after_restart(mut client: Sleeve, port: &Path, image: &[u8]) -> anyhow::Result<()> {
    let p = port.display();
    let mut client = match client.reconnect() {
        Ok(_) => client,
        Err(_) => {
            drop(client);
            reopen(port)?
        }
    };
    let lost = || {
        anyhow::anyhow!(
            "{p}: the sleeve restarted during the upload (a power cut or a reset?); \
             the upload was lost: run it again"
        )
    };
    match client.verify(image, |_| {}) {
        Ok(()) => {}
        Err(ClientError::Verify(_)) => return Err(lost()),
        Err(e) => return Err(describe(e, port, "verify")),
    }
    let slots = match client.info().map_err(|e| describe(e, port, "info"))?.bank {
        touch_protocol::link::BankState::Flashed(s) => s.slots,
        _ => return Err(lost()),
    };
    eprintln!(
        "touchc: {p}: the sleeve restarted before it answered the upload's commit (a power cut \
         or a reset?), with the new bank in place: verified {} bytes, {slots} slots",
        image.len()
    );
    Ok(())
}

/// Refuses a stimulus compiled for another layout than the sleeve's, naming both.
fn same_layout(s: &Stimulus<'_>, info: &touchc_link::DeviceInfo, what: &str) -> anyhow::Result<()> {
    let h = s.header();
    if h.layout_hash != info.layout_hash {
        bail!(
            "{what} was compiled for layout \"{}\" (geometry {:#010x}), but the sleeve drives \"{}\" \
             (geometry {:#010x}); compile it with the sleeve's layout. Nothing was sent",
            escaped(h.layout),
            h.layout_hash,
            escaped(&info.layout),
            info.layout_hash
        );
    }
    Ok(())
}

/// Opens `port` again after the sleeve restarted, for as long as a restart takes.
fn reopen(port: &Path) -> anyhow::Result<Sleeve> {
    let limit = touchc_link::Timeouts::default().restart;
    let start = std::time::Instant::now();
    loop {
        match open(port) {
            Ok(c) => return Ok(c),
            Err(e) if start.elapsed() >= limit => {
                return Err(e.context(format!(
                    "{}: the sleeve did not come back after its restart",
                    port.display()
                )))
            }
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    }
}

/// Ends an upload left unfinished: the sleeve restarts into its built-in bank.
pub(super) fn abort(port: Option<&Path>) -> anyhow::Result<()> {
    let Link { port, mut client } = connect(port)?;
    match client.abort_upload() {
        Ok(()) => {}
        Err(ClientError::Refused {
            error: LinkError::NoUpload,
            ..
        }) => {
            eprintln!(
                "touchc: {}: no upload in progress; nothing to abort",
                port.display()
            );
            return Ok(());
        }
        Err(e) => return Err(describe(e, &port, "abort")),
    }
    client
        .reconnect()
        .map_err(|e| describe(e, &port, "abort (the restart)"))?;
    eprintln!(
        "touchc: {}: the unfinished upload is ended; the sleeve restarted into its built-in bank",
        port.display()
    );
    Ok(())
}

pub(super) fn stream(port: Option<&Path>, file: &Path) -> anyhow::Result<()> {
    let bytes = crate::cli::input::read_input(file)?;
    let stimulus = Stimulus::decode(&bytes).with_context(|| {
        format!(
            "{}: not a valid stimulus",
            crate::cli::input::input_name(file)
        )
    })?;
    let Link { port, mut client } = connect(port)?;
    let info = client.info().map_err(|e| describe(e, &port, "info"))?;
    same_layout(&stimulus, &info, &crate::cli::input::input_name(file))?;
    let bar = bar(u64::from(stimulus.header().keyframe_count), "keyframes");
    let r = client
        .stream(&stimulus, |p: Progress| bar.set_position(p.done))
        .map_err(|e| describe(e, &port, "stream"));
    bar.finish_and_clear();
    r?;
    // The sleeve plays out what it holds: wait for the end, reporting a cut.
    let hold = Duration::from_millis(u64::from(stimulus.header().playback_ms()) + 2000);
    let start = std::time::Instant::now();
    while start.elapsed() < hold {
        let Some(e) = client
            .next_event(Duration::from_millis(200))
            .map_err(|e| describe(e, &port, "stream"))?
        else {
            continue;
        };
        match e.event {
            Event::Finished(Source::Stream) => {
                eprintln!(
                    "touchc: {}: streamed {}",
                    port.display(),
                    crate::cli::input::input_name(file)
                );
                return Ok(());
            }
            Event::LimitHit { kind, channel, .. } => {
                bail!("{}: the stream hit the {} limit on channel {channel}; the sleeve ramped to 0 A", port.display(), limit_name(kind))
            }
            Event::StreamStopped(why @ (StreamStop::Deadline | StreamStop::Underrun)) => {
                bail!("{}: {}", port.display(), super::stream_stopped(why))
            }
            _ => {}
        }
    }
    Ok(())
}
