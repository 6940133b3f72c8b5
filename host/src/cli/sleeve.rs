//! `touchc sleeve ...`: a sleeve on a cable (its USB socket, or its USART through a
//! USB-serial adapter): list, info, upload, play, stop, stream, status, events.
//!
//! Every subcommand but `list` opens one port (`--port`, or the only candidate),
//! says hello (the link version must match), and does one thing. The sleeve
//! decides: a refused command is reported in words and nothing changed on it.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{anyhow, bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use touch_protocol::link::{BankState, Event, Gesture, Limit, LinkError, Source, StreamStop};
use touch_protocol::{bank, Stimulus};
use touchc::link::serial::{self, Candidate, SerialTransport};
use touchc::link::{Client, ClientError, Progress, Stamped};

use super::{escaped, usage};

/// The USB vendor and product id a sleeve's own USB socket would present (pid.codes'
/// test pair): such a port is listed first. The firmware's link is on its USART, so
/// in practice every port is a USB-serial adapter.
pub const USB_IDS: (u16, u16) = (0x1209, 0x0001);

/// What `--help` says after the subcommands.
const AFTER_HELP: &str = "\
Port: --port PATH, else the only USB serial port attached: a USB-serial adapter on
the sleeve's USART2 (PA2 TX, PA3 RX, 460800 8N1). Name it with --port when there
are several.

Exit status: 0 success, 1 no sleeve attached or the sleeve refused or failed, 2 usage.";

/// Arguments of `touchc sleeve`.
#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The sleeve's serial port (`/dev/ttyACM0`, `/dev/ttyUSB0`).
    #[arg(long, global = true, value_name = "PATH")]
    port: Option<PathBuf>,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Debug, clap::Subcommand)]
enum Cmd {
    /// List the USB serial ports a sleeve may be on.
    List {
        /// Ask each port for the sleeve's info (sends a few bytes to every port).
        #[arg(long)]
        probe: bool,
    },
    /// Show the sleeve: firmware, layout, limits, its bank and slots.
    Info {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Upload a bank image, or stimuli packed into one (slot 0 first), then verify it.
    Upload {
        /// A `.bank` image, or `.touch` stimuli, one per slot.
        #[arg(required = true, value_name = "BANK | STIMULUS...")]
        files: Vec<PathBuf>,
        /// The layout TOML the stimuli must be compiled for (as `touchc bank`).
        #[arg(long)]
        layout: Option<PathBuf>,
    },
    /// Play a slot of the sleeve's bank; prints the tick of its first frame.
    Play {
        /// The slot, from 0.
        slot: u8,
        /// Print JSON (with the host's clock) instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Stop what plays (the outputs ramp to 0 A); prints the tick the ramp began.
    Stop {
        /// Print JSON (with the host's clock) instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Stream a stimulus to the sleeve while it plays (no data for 50 ms: 0 A).
    Stream {
        /// The `.touch` stimulus.
        file: PathBuf,
    },
    /// Show what plays, each coil's heat and the last fault.
    Status {
        /// Show it again every `--interval` until interrupted.
        #[arg(long)]
        watch: bool,
        /// Time between two readings with `--watch`, ms.
        #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(20..=60_000))]
        interval: u64,
        /// Print JSON lines instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Print the sleeve's events as JSON lines (device tick and host clock), for
    /// experiment logs.
    Events {
        /// Stop after this many events.
        #[arg(long)]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long, value_name = "SECONDS")]
        duration: Option<f64>,
    },
}

/// Runs `touchc sleeve`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    match &args.command {
        Cmd::List { probe } => list(*probe),
        Cmd::Info { json } => info(args.port.as_deref(), *json),
        Cmd::Upload { files, layout } => upload(args.port.as_deref(), files, layout.as_deref()),
        Cmd::Play { slot, json } => play(args.port.as_deref(), *slot, *json),
        Cmd::Stop { json } => stop(args.port.as_deref(), *json),
        Cmd::Stream { file } => stream(args.port.as_deref(), file),
        Cmd::Status {
            watch,
            interval,
            json,
        } => status(args.port.as_deref(), *watch, *interval, *json),
        Cmd::Events { count, duration } => events(args.port.as_deref(), *count, *duration),
    }
}

type Sleeve = Client<SerialTransport>;

/// A sleeve the command talks to: its port and the client.
struct Link {
    port: PathBuf,
    client: Sleeve,
}

/// The port to use: `--port`, else the only candidate.
fn choose_port(port: Option<&Path>) -> anyhow::Result<PathBuf> {
    if let Some(p) = port {
        return Ok(p.to_path_buf());
    }
    let found = serial::candidates(USB_IDS).context("cannot list the serial ports")?;
    let sleeves: Vec<&Candidate> = found.iter().filter(|c| c.is_sleeve).collect();
    match (sleeves.as_slice(), found.as_slice()) {
        ([one], _) => Ok(one.path.clone()),
        ([], [one]) => Ok(one.path.clone()),
        ([], []) => bail!("no sleeve attached (no USB serial port found); connect one, or name its port with --port"),
        _ => bail!(
            "several serial ports may be a sleeve ({}); choose one with --port",
            found
                .iter()
                .map(|c| c.path.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Opens the sleeve's port and checks that it speaks this link version.
fn connect(port: Option<&Path>) -> anyhow::Result<Link> {
    let port = choose_port(port)?;
    let client = open(&port)?;
    Ok(Link { port, client })
}

fn open(port: &Path) -> anyhow::Result<Sleeve> {
    let transport = match SerialTransport::open(port) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            bail!(
                "{}: no sleeve attached there (no such port)",
                port.display()
            )
        }
        Err(e) => return Err(e).with_context(|| format!("{}: cannot open", port.display())),
    };
    let mut client = Client::new(transport);
    client.hello().map_err(|e| describe(e, port, "hello"))?;
    Ok(client)
}

/// One sentence for a failed link operation, naming the port.
fn describe(e: ClientError, port: &Path, what: &str) -> anyhow::Error {
    let p = port.display();
    match e {
        ClientError::Timeout { waited, .. } => anyhow!(
            "{p}: no sleeve answered ({what}: no reply within {} ms)",
            waited.as_millis()
        ),
        ClientError::Version { device, host } => {
            anyhow!(
            "{p}: the sleeve's firmware speaks link version {device}, this touchc version {host}; \
             update {}",
            if device < host { "the firmware" } else { "touchc" }
        )
        }
        ClientError::Refused { error, .. } => anyhow!("{p}: {what} refused: {}", refusal(&error)),
        ClientError::Io(io) => anyhow!("{p}: the link failed during {what}: {io}"),
        other => anyhow!("{p}: {what}: {other}"),
    }
}

/// Why the sleeve refused, in words.
fn refusal(e: &LinkError) -> String {
    match *e {
        LinkError::Malformed => "the sleeve could not take the request (malformed)".into(),
        LinkError::UnsupportedVersion { device } => {
            format!("the sleeve speaks link version {device}")
        }
        LinkError::NoSuchSlot { slot, slots } => match slots {
            0 => format!("slot {slot} does not exist: the sleeve's bank has no slots"),
            n => format!(
                "slot {slot} does not exist: the sleeve's bank has {n} slot{} (0-{})",
                if n == 1 { "" } else { "s" },
                n - 1
            ),
        },
        LinkError::BadSlot { slot } => format!(
            "slot {slot} was compiled for another layout than the sleeve's; the firmware never plays it"
        ),
        LinkError::TooHot {
            channel,
            permille,
            cooldown_ms,
        } => format!(
            "coil {channel} is too hot to start ({:.0} % of its heat budget); try again in {:.1} s",
            f64::from(permille) / 10.0,
            f64::from(cooldown_ms) / 1000.0
        ),
        LinkError::Busy(b) => format!(
            "the sleeve is busy ({}); stop it first",
            match b {
                touch_protocol::link::Busy::Playing => "something plays",
                touch_protocol::link::Busy::Uploading => "an upload is in progress",
                touch_protocol::link::Busy::Streaming => "a stream plays",
            }
        ),
        LinkError::NoBank => "the sleeve has no playable bank".into(),
        LinkError::NoUpload => "no upload in progress".into(),
        LinkError::OutOfOrder { expected } => {
            format!("chunk out of order (the sleeve expects offset {expected})")
        }
        LinkError::OutOfRange => "offset or length outside the bank region".into(),
        LinkError::BadCrc { expected, computed } => format!(
            "the image arrived damaged (CRC {computed:#010x}, announced {expected:#010x}); the bank region is left erased"
        ),
        LinkError::WrongLayout { slot } => format!(
            "slot {slot} of the bank was compiled for another layout than the sleeve's; the bank region is left erased"
        ),
        LinkError::BadBank { blinks } => {
            format!("not a valid bank (boot LED code {blinks}); the bank region is left erased")
        }
        LinkError::Flash => "the sleeve's flash did not erase or program".into(),
        LinkError::NoStream => "no stream in progress".into(),
        LinkError::StreamGap { expected } => {
            format!("stream keyframes out of order (the sleeve expects {expected})")
        }
        LinkError::StreamFull { room } => format!("the sleeve's stream buffer is full ({room} free)"),
    }
}

fn list(probe: bool) -> anyhow::Result<()> {
    let found = serial::candidates(USB_IDS).context("cannot list the serial ports")?;
    if found.is_empty() {
        bail!("no sleeve attached (no USB serial port found)");
    }
    let mut out = std::io::stdout().lock();
    for c in &found {
        let (vid, pid) = c.usb.unwrap_or((0, 0));
        let kind = if c.is_sleeve {
            "sleeve (USB)"
        } else {
            "USB-serial adapter"
        };
        let mut line = format!("{}  {kind}  {vid:04x}:{pid:04x}", c.path.display());
        if let Some(p) = &c.product {
            line.push_str(&format!("  {}", escaped(p)));
        }
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

fn info(port: Option<&Path>, as_json: bool) -> anyhow::Result<()> {
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
    let bank = match i.bank {
        BankState::Flashed(s) => {
            json!({"state": "flashed", "bytes": s.len, "slots": s.slots})
        }
        BankState::Builtin(s) => {
            json!({"state": "builtin", "bytes": s.len, "slots": s.slots})
        }
        BankState::Refused { blinks } => json!({"state": "refused", "led_code": blinks}),
    };
    let mut out = std::io::stdout().lock();
    if as_json {
        let v = json!({
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
        });
        writeln!(out, "{v}")?;
        return Ok(());
    }
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
    for s in &entries {
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

/// A progress bar for `len` units of `what`, on standard error.
fn bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template(&format!("{{bar:40}} {{pos}}/{{len}} {what}, {{elapsed}}"))
    {
        bar.set_style(style);
    }
    bar
}

/// The image to upload: a bank file as it is, or the stimuli packed into one.
fn image_of(files: &[PathBuf], layout: Option<&Path>) -> anyhow::Result<Vec<u8>> {
    if let [one] = files {
        let bytes = super::read_input(one)?;
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
    Ok(super::bank::build(files, layout, Path::new("the bank"))?.0)
}

fn upload(port: Option<&Path>, files: &[PathBuf], layout: Option<&Path>) -> anyhow::Result<()> {
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
    let slots = client
        .upload(&image, |p: Progress| bar.set_position(p.done))
        .map_err(|e| describe(e, &port, "upload"));
    bar.finish_and_clear();
    let slots = slots?;
    // The sleeve restarts into the new bank (a USB socket goes away and comes back).
    drop(client);
    let mut client = reopen(&port)?;
    let bar = self::bar(image.len() as u64, "bytes read back");
    let verified = client
        .verify(&image, |p: Progress| bar.set_position(p.done))
        .map_err(|e| describe(e, &port, "verify"));
    bar.finish_and_clear();
    verified?;
    eprintln!(
        "touchc: {}: uploaded and verified {} bytes, {} slots",
        port.display(),
        image.len(),
        slots
    );
    Ok(())
}

/// Refuses a stimulus compiled for another layout than the sleeve's, naming both.
fn same_layout(
    s: &Stimulus<'_>,
    info: &touchc::link::DeviceInfo,
    what: &str,
) -> anyhow::Result<()> {
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
    let limit = touchc::link::Timeouts::default().restart;
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

fn unix_s(t: SystemTime) -> f64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

fn play(port: Option<&Path>, slot: u8, as_json: bool) -> anyhow::Result<()> {
    let Link { port, mut client } = connect(port)?;
    let started = client
        .play(slot)
        .map_err(|e| describe(e, &port, &format!("play {slot}")))?;
    let host = unix_s(SystemTime::now());
    if as_json {
        println!(
            "{}",
            json!({"slot": slot, "tick": started.tick, "now": started.now, "host_unix_s": host})
        );
    } else if started.now {
        println!("slot {slot} started at tick {}", started.tick);
    } else {
        println!(
            "slot {slot} starts after the ramp down that began at tick {}",
            started.tick
        );
    }
    Ok(())
}

fn source_json(s: Source) -> serde_json::Value {
    match s {
        Source::Slot(n) => json!({"source": "slot", "slot": n}),
        Source::Stream => json!({"source": "stream"}),
    }
}

fn stop(port: Option<&Path>, as_json: bool) -> anyhow::Result<()> {
    let Link { port, mut client } = connect(port)?;
    let (source, tick) = client.stop().map_err(|e| describe(e, &port, "stop"))?;
    let host = unix_s(SystemTime::now());
    if as_json {
        let mut v = json!({"tick": tick, "host_unix_s": host, "stopped": source.is_some()});
        if let (Some(s), Some(m)) = (source, v.as_object_mut()) {
            if let serde_json::Value::Object(src) = source_json(s) {
                m.extend(src);
            }
        }
        println!("{v}");
    } else {
        match source {
            Some(Source::Slot(n)) => println!("slot {n} ramps to 0 A from tick {tick}"),
            Some(Source::Stream) => println!("the stream ramps to 0 A from tick {tick}"),
            None => println!("nothing was playing (tick {tick})"),
        }
    }
    Ok(())
}

fn stream(port: Option<&Path>, file: &Path) -> anyhow::Result<()> {
    let bytes = super::read_input(file)?;
    let stimulus = Stimulus::decode(&bytes)
        .with_context(|| format!("{}: not a valid stimulus", super::input_name(file)))?;
    let Link { port, mut client } = connect(port)?;
    let info = client.info().map_err(|e| describe(e, &port, "info"))?;
    same_layout(&stimulus, &info, &super::input_name(file))?;
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
                    super::input_name(file)
                );
                return Ok(());
            }
            Event::LimitHit { kind, channel, .. } => {
                bail!("{}: the stream hit the {} limit on channel {channel}; the sleeve ramped to 0 A", port.display(), limit_name(kind))
            }
            Event::StreamStopped(StreamStop::Deadline | StreamStop::Underrun) => {
                bail!(
                    "{}: the stream starved (the host fell behind); the sleeve ramped to 0 A",
                    port.display()
                )
            }
            _ => {}
        }
    }
    Ok(())
}

fn limit_name(k: Limit) -> &'static str {
    match k {
        Limit::Peak => "peak current",
        Limit::Slew => "slew",
        Limit::Thermal => "thermal",
    }
}

fn status(port: Option<&Path>, watch: bool, interval_ms: u64, as_json: bool) -> anyhow::Result<()> {
    let Link { port, mut client } = connect(port)?;
    let mut out = std::io::stdout().lock();
    loop {
        let s = client.status().map_err(|e| describe(e, &port, "status"))?;
        let host = unix_s(SystemTime::now());
        if as_json {
            let v = json!({
                "tick": s.tick,
                "host_unix_s": host,
                "playing": s.playing.map(source_json),
                "stopping": s.stopping,
                "selected": s.selected,
                "heat_permille": s.heat_permille,
                "cooldown_ms": s.cooldown_ms,
                "faults": s.faults,
                "last_fault": s.last_fault.map(|f| json!({
                    "tick": f.tick, "limit": limit_name(f.kind), "channel": f.channel,
                    "playing": source_json(f.source),
                })),
                "upload_bytes": s.upload,
            });
            writeln!(out, "{v}")?;
        } else {
            let playing = match (s.playing, s.stopping) {
                (None, _) => "at rest".to_string(),
                (Some(Source::Slot(n)), false) => format!("playing slot {n}"),
                (Some(Source::Stream), false) => "streaming".to_string(),
                (Some(Source::Slot(n)), true) => format!("slot {n} ramping to 0 A"),
                (Some(Source::Stream), true) => "stream ramping to 0 A".to_string(),
            };
            let heat: Vec<String> = s.heat_permille.iter().map(|h| format!("{h:>3}")).collect();
            let mut line = format!(
                "tick {}  {playing}  selected {}  heat per mille [{}]",
                s.tick,
                s.selected,
                heat.join(" ")
            );
            if s.cooldown_ms > 0 {
                line.push_str(&format!(
                    "  cooling {:.1} s",
                    f64::from(s.cooldown_ms) / 1000.0
                ));
            }
            if let Some(f) = s.last_fault {
                line.push_str(&format!(
                    "  faults {} (last: {} limit, channel {}, tick {})",
                    s.faults,
                    limit_name(f.kind),
                    f.channel,
                    f.tick
                ));
            }
            if let Some(b) = s.upload {
                line.push_str(&format!("  upload at {b} bytes"));
            }
            writeln!(out, "{line}")?;
        }
        out.flush()?;
        if !watch {
            return Ok(());
        }
        client
            .pump(Duration::from_millis(interval_ms))
            .map_err(|e| describe(e, &port, "status"))?;
    }
}

/// One event as a JSON object: tick, host clock, and what happened, flat.
pub(crate) fn event_json(e: &Stamped) -> serde_json::Value {
    let mut v = json!({"tick": e.tick, "host_unix_s": unix_s(e.received)});
    let extra = match e.event {
        Event::Button(g) => match g {
            Gesture::Toggle => json!({"event": "button", "gesture": "toggle"}),
            Gesture::Next => json!({"event": "button", "gesture": "next"}),
            Gesture::Slot(n) => json!({"event": "button", "gesture": "slot", "slot": n}),
        },
        Event::Started(s) => with("started", source_json(s)),
        Event::Stopping(s) => with("stopping", source_json(s)),
        Event::Finished(s) => with("finished", source_json(s)),
        Event::LimitHit {
            source,
            kind,
            channel,
        } => {
            let mut x = with("limit_hit", source_json(source));
            x["limit"] = json!(limit_name(kind));
            x["channel"] = json!(channel);
            x
        }
        Event::TooHot {
            source,
            channel,
            permille,
            cooldown_ms,
        } => {
            let mut x = with("too_hot", source_json(source));
            x["channel"] = json!(channel);
            x["heat_permille"] = json!(permille);
            x["cooldown_ms"] = json!(cooldown_ms);
            x
        }
        Event::Selected(n) => json!({"event": "selected", "slot": n}),
        Event::BadSlot(n) => json!({"event": "bad_slot", "slot": n}),
        Event::StreamStopped(r) => json!({"event": "stream_stopped", "reason": match r {
            StreamStop::Deadline => "deadline",
            StreamStop::Underrun => "underrun",
            StreamStop::Ended => "ended",
        }}),
    };
    if let (Some(m), serde_json::Value::Object(x)) = (v.as_object_mut(), extra) {
        m.extend(x);
    }
    v
}

fn with(event: &str, mut source: serde_json::Value) -> serde_json::Value {
    source["event"] = json!(event);
    source
}

fn events(port: Option<&Path>, count: Option<u64>, duration: Option<f64>) -> anyhow::Result<()> {
    if let Some(d) = duration {
        if !(d.is_finite() && d >= 0.0) {
            return Err(usage(format!("--duration {d}: not a number of seconds")));
        }
    }
    let Link { port, mut client } = connect(port)?;
    let until = duration.map(|d| std::time::Instant::now() + Duration::from_secs_f64(d));
    let mut out = std::io::stdout().lock();
    let mut seen = 0u64;
    while count.is_none_or(|c| seen < c) {
        let wait = match until {
            Some(u) => {
                let now = std::time::Instant::now();
                if now >= u {
                    break;
                }
                (u - now).min(Duration::from_millis(200))
            }
            None => Duration::from_millis(200),
        };
        if let Some(e) = client
            .next_event(wait)
            .map_err(|e| describe(e, &port, "events"))?
        {
            writeln!(out, "{}", event_json(&e))?;
            out.flush()?;
            seen += 1;
        }
    }
    Ok(())
}
