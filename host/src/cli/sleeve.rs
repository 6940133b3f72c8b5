//! `touchc sleeve ...`: a sleeve on a cable (its USB socket, or its USART through a
//! USB-serial adapter): list, info, upload, play, stop, stream, status, events.
//!
//! Every subcommand but `list` opens one port (`--port`, or the only candidate),
//! says hello (the link version must match), and does one thing. The sleeve
//! decides: a refused command is reported in words and nothing changed on it.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{anyhow, bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use touch_protocol::link::{Limit, LinkError, Source, StreamStop, STREAM_DEADLINE_MS};
use touchc_link::serial::{self, Candidate, SerialTransport};
use touchc_link::{Client, ClientError};

mod info;
mod playback;
mod transfer;
mod watch;

use info::{info, list};
use playback::{play, stop};
use transfer::{abort, stream, upload};
use watch::{events, status};

/// The USB vendor and product id a sleeve's own USB socket would present (pid.codes'
/// test pair): such a port is listed first. The firmware's link is on its USART, so
/// in practice every port is a USB-serial adapter.
pub const USB_IDS: (u16, u16) = (0x1209, 0x0001);

/// Seconds after an upload's last request at which the sleeve gives it up
/// (`sleeve_firmware::link::server::UPLOAD_IDLE_MS`, the firmware's rule).
const UPLOAD_IDLE_S: u32 = 10;

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
    /// End an upload left unfinished (its program killed or unplugged): the sleeve
    /// restarts into its built-in bank. The sleeve ends one by itself 10 s after its
    /// last chunk.
    Abort,
    /// Stream a stimulus to the sleeve while it plays (its buffer run dry and no
    /// data for 50 ms: 0 A).
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
        Cmd::Abort => abort(args.port.as_deref()),
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

/// Where the firmware twin serves a sleeve by default (`bash firmware/twin/run.sh
/// serve`): a link to its pseudo-terminal, in the temporary directory.
fn twin_port() -> PathBuf {
    std::env::temp_dir().join("touchc-sleeve-twin")
}

/// The twin's port, if a twin serves there now: the link leads to a terminal and the
/// process the twin wrote beside it (`touchc-sleeve-twin.pid`) is alive. A twin that
/// was killed leaves its link behind, and the terminal it named can be another
/// program's by now.
fn running_twin() -> Option<PathBuf> {
    let p = twin_port();
    let target = std::fs::canonicalize(&p).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if !std::fs::metadata(&target)
            .ok()?
            .file_type()
            .is_char_device()
        {
            return None;
        }
        let pid = std::fs::read_to_string(p.with_extension("pid")).ok()?;
        if !alive(pid.trim().parse().ok()?) {
            return None;
        }
    }
    #[cfg(not(unix))]
    let _ = target;
    Some(p)
}

/// Whether process `pid` exists (`kill(pid, 0)`: it succeeds, or is refused for want
/// of permission).
#[cfg(unix)]
fn alive(pid: i32) -> bool {
    extern "C" {
        fn kill(pid: i32, sig: i32) -> i32;
    }
    const EPERM: i32 = 1;
    if pid <= 0 {
        return false;
    }
    // SAFETY: signal 0 sends nothing; it only asks whether the process exists.
    let sent = unsafe { kill(pid, 0) };
    sent == 0 || std::io::Error::last_os_error().raw_os_error() == Some(EPERM)
}

/// The port to use: `--port`, else the only sleeve (a running twin counts), else
/// the only candidate.
fn choose_port(port: Option<&Path>) -> anyhow::Result<PathBuf> {
    if let Some(p) = port {
        return Ok(p.to_path_buf());
    }
    let mut found = serial::candidates(USB_IDS).context("cannot list the serial ports")?;
    if let Some(twin) = running_twin() {
        found.push(Candidate {
            path: twin,
            usb: None,
            product: None,
            serial: None,
            is_sleeve: true,
        });
    }
    let sleeves: Vec<&Candidate> = found.iter().filter(|c| c.is_sleeve).collect();
    match (sleeves.as_slice(), found.as_slice()) {
        ([one], _) => Ok(one.path.clone()),
        ([], [one]) => Ok(one.path.clone()),
        ([], []) => bail!(
            "no sleeve attached (no USB serial port found); connect one, or name its port with \
             --port (without hardware: `bash firmware/twin/run.sh serve` in the workspace)"
        ),
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
        Err(e) if e.kind() == std::io::ErrorKind::ResourceBusy => {
            bail!(
                "{}: {e}; the sleeve answers one program at a time: close that one, or wait until it is done",
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
        ClientError::StreamStopped(why) => anyhow!("{p}: {}", stream_stopped(why)),
        ClientError::Io(io) => anyhow!("{p}: the link failed during {what}: {io}"),
        other => anyhow!("{p}: {what}: {other}"),
    }
}

/// Why the sleeve stopped a stream, in words.
fn stream_stopped(why: StreamStop) -> String {
    match why {
        StreamStop::Deadline => format!(
            "the sleeve stopped the stream: its buffer ran dry and no data came within its \
             {STREAM_DEADLINE_MS} ms deadline (this computer fell behind); it ramped to 0 A"
        ),
        StreamStop::Underrun => "the sleeve stopped the stream: a keyframe was due before it \
             arrived (its buffer ran dry: this computer fell behind); it ramped to 0 A"
            .into(),
        StreamStop::Ended => "the sleeve ended the stream before every keyframe was sent".into(),
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
        LinkError::Busy(touch_protocol::link::Busy::Uploading) => format!(
            "the sleeve is busy: an upload is in progress, or was left unfinished; \
             `touchc sleeve abort` ends it (the sleeve restarts into its built-in bank), \
             as the sleeve does {} s after the upload's last chunk",
            UPLOAD_IDLE_S
        ),
        LinkError::Busy(b) => format!(
            "the sleeve is busy ({}); `touchc sleeve stop` stops it",
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
        LinkError::QueueFull => {
            "the sleeve's command queue was full (requests came faster than it answers); nothing was done"
                .into()
        }
    }
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

fn unix_s(t: SystemTime) -> f64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

fn source_json(s: Source) -> serde_json::Value {
    match s {
        Source::Slot(n) => json!({"source": "slot", "slot": n}),
        Source::Stream => json!({"source": "stream"}),
    }
}

fn limit_name(k: Limit) -> &'static str {
    match k {
        Limit::Peak => "peak current",
        Limit::Slew => "slew",
        Limit::Thermal => "thermal",
    }
}
