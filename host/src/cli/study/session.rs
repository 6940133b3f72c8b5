//! `touchc study run`: one participant's session. The loop owns the sleeve, the log
//! and the page's state; it plays each trial, then waits for the page's answer,
//! serving the page all the while.

use std::collections::HashSet;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{anyhow, bail, Context};
use serde::Deserialize;
use serde_json::json;
use touch_protocol::link::{Event, Source};
use touchc_link::serial::{self, SerialTransport};
use touchc_link::{Client, ClientError};
use touchc_study::log::{self, EventRecord, Record, Session, TrialRecord};

use super::http::{Request, Response, Server};
use super::plan::Plan;

const PAGE: &str = include_str!("page.html");

type Sleeve = Client<SerialTransport>;

/// What the page shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Intro,
    Acclimation,
    Playing,
    Classify,
    Sam,
    Paused,
    Done,
}

/// An answer from the page.
#[derive(Debug, Deserialize)]
struct Answer {
    id: u64,
    p: Option<Vec<f64>>,
    valence: Option<f64>,
    arousal: Option<f64>,
}

/// The session's state as the page sees it, and what the page asked for.
struct Ui<'a> {
    plan: &'a Plan,
    server: Server,
    phase: Phase,
    id: u64,
    round: u32,
    position: u32,
    of: u32,
    message: String,
    started: bool,
    answer: Option<Answer>,
    replay: bool,
}

impl Ui<'_> {
    fn state(&self) -> String {
        let phase = format!("{:?}", self.phase).to_lowercase();
        let scenarios: Vec<_> = self
            .plan
            .scenarios
            .iter()
            .enumerate()
            .map(|(i, s)| json!({"name": s.name, "prompt": s.prompt, "audio": s.audio.as_ref().map(|_| format!("/audio/{i}"))}))
            .collect();
        json!({
            "phase": phase, "id": self.id, "round": self.round, "rounds": self.plan.rounds,
            "position": self.position, "of": self.of, "message": self.message,
            "replay": self.plan.replay, "scenarios": scenarios,
        })
        .to_string()
    }

    /// Checks an answer against the phase it is for.
    fn take(&mut self, a: Answer) -> Result<(), String> {
        if a.id != self.id || !matches!(self.phase, Phase::Classify | Phase::Sam) {
            return Err("this trial is not waiting for an answer".into());
        }
        if self.phase == Phase::Classify {
            let p = a.p.as_ref().ok_or("p is missing")?;
            if p.len() != self.plan.scenarios.len() || p.iter().any(|v| !v.is_finite() || *v < 0.0)
            {
                return Err("one probability >= 0 per scenario".into());
            }
            let top = p.iter().copied().fold(0.0, f64::max);
            if top <= 0.0 {
                return Err("move at least one slider".into());
            }
            if p.iter().filter(|v| **v == top).count() > 1 {
                return Err("two scenarios share the largest value".into());
            }
        } else {
            let ok =
                |v: Option<f64>| v.is_some_and(|v| (1.0..=9.0).contains(&v) && v.fract() == 0.0);
            if !ok(a.valence) || !ok(a.arousal) {
                return Err("valence and arousal are whole numbers 1 to 9".into());
            }
        }
        self.answer = Some(a);
        Ok(())
    }

    fn handle(&mut self, r: Request) {
        let resp = match (r.method.as_str(), r.path.as_str()) {
            ("GET", "/") => Response::ok("text/html; charset=utf-8", PAGE),
            ("GET", "/state") => Response::ok("application/json", self.state()),
            ("GET", p) if p.starts_with("/audio/") => {
                let audio = p[7..]
                    .parse::<usize>()
                    .ok()
                    .and_then(|i| self.plan.scenarios.get(i)?.audio.as_ref());
                match audio {
                    Some((bytes, mime)) => Response::ok(mime, bytes.clone()),
                    None => Response::error(404, "no such audio"),
                }
            }
            ("POST", "/start") => {
                self.started = true;
                Response::ok("text/plain", "ok")
            }
            ("POST", "/replay")
                if self.plan.replay && matches!(self.phase, Phase::Classify | Phase::Sam) =>
            {
                self.replay = true;
                Response::ok("text/plain", "ok")
            }
            ("POST", "/answer") => match serde_json::from_slice::<Answer>(&r.body) {
                Ok(a) => match self.take(a) {
                    Ok(()) => Response::ok("text/plain", "ok"),
                    Err(e) => Response::error(409, &e),
                },
                Err(e) => Response::error(400, &e.to_string()),
            },
            _ => Response::error(404, "not found"),
        };
        r.respond(resp);
    }

    /// Serves the page for `d`.
    fn serve_for(&mut self, d: Duration) {
        let until = Instant::now() + d;
        while Instant::now() < until {
            self.serve();
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn serve(&mut self) {
        while let Some(r) = self.server.poll() {
            self.handle(r);
        }
    }
}

/// The session's log, appended to and synced after every record.
struct LogFile {
    path: PathBuf,
    file: File,
}

impl LogFile {
    fn append(&mut self, r: &Record) -> anyhow::Result<()> {
        let what = || self.path.display().to_string();
        self.file
            .write_all(r.line().as_bytes())
            .with_context(what)?;
        self.file.sync_data().with_context(what)
    }
}

fn now_s() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// Opens the sleeve (`--port`, else the only USB serial port) and says hello.
fn open_sleeve(port: Option<&Path>) -> anyhow::Result<(PathBuf, Sleeve)> {
    let path = match port {
        Some(p) => p.to_path_buf(),
        None => {
            let found = serial::candidates(crate::cli::sleeve::USB_IDS)
                .context("cannot list the serial ports")?;
            match found.as_slice() {
                [] => bail!("no sleeve attached (no USB serial port found); connect one, or name its port with --port"),
                [one] => one.path.clone(),
                _ => bail!("several serial ports may be a sleeve; choose one with --port"),
            }
        }
    };
    let t = match SerialTransport::open(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            bail!(
                "{}: no sleeve attached there (no such port)",
                path.display()
            )
        }
        Err(e) => return Err(e).with_context(|| format!("{}: cannot open", path.display())),
    };
    let mut c = Client::new(t);
    c.hello()
        .map_err(|e| anyhow!("{}: no sleeve answered: {e}", path.display()))?;
    Ok((path, c))
}

/// Plays `slot` until the sleeve reports its end; a refusal (a coil too hot, no
/// bank) is logged and retried after the plan's pause, never skipped. Returns the
/// start and end ticks.
fn play(
    ui: &mut Ui,
    sleeve: &mut Sleeve,
    log: &mut LogFile,
    slot: u8,
    length_ms: u32,
) -> anyhow::Result<(u32, Option<u32>)> {
    loop {
        let refusal = match sleeve.play(slot) {
            Ok(started) => match wait_end(ui, sleeve, slot, length_ms)? {
                Ok(end) => return Ok((started.tick, end)),
                Err(why) => why,
            },
            Err(ClientError::Refused { error, .. }) => format!("{error:?}"),
            Err(e) => return Err(anyhow!("the sleeve failed: {e}")),
        };
        eprintln!(
            "slot {slot} refused ({refusal}); trying again in {} s",
            ui.plan.retry_pause_s
        );
        log.append(&Record::Event(EventRecord {
            what: "refused".into(),
            detail: format!("slot {slot}: {refusal}"),
        }))?;
        let before = ui.phase;
        ui.phase = Phase::Paused;
        ui.message = "A short pause: the sleeve is cooling down.".into();
        ui.serve_for(Duration::from_secs_f64(ui.plan.retry_pause_s));
        ui.phase = before;
        ui.message.clear();
    }
}

/// Waits for the end of `slot`: `Ok(Ok(end tick))`, or `Ok(Err(why))` if the sleeve
/// refused or cut it short.
fn wait_end(
    ui: &mut Ui,
    sleeve: &mut Sleeve,
    slot: u8,
    length_ms: u32,
) -> anyhow::Result<Result<Option<u32>, String>> {
    let until = Instant::now() + Duration::from_millis(length_ms as u64 + 3000);
    while Instant::now() < until {
        ui.serve();
        let ev = sleeve
            .next_event(Duration::from_millis(20))
            .map_err(|e| anyhow!("the sleeve failed: {e}"))?;
        match ev.map(|e| e.event) {
            Some(Event::Finished(Source::Slot(s))) if s == slot => {
                return Ok(Ok(Some(ev.map_or(0, |e| e.tick))))
            }
            Some(Event::TooHot { cooldown_ms, .. }) => {
                return Ok(Err(format!("too hot, cooling {cooldown_ms} ms")))
            }
            Some(Event::LimitHit { kind, .. }) => return Ok(Err(format!("limit hit: {kind:?}"))),
            _ => {}
        }
    }
    Ok(Ok(None))
}

/// Arguments of `touchc study run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// The study plan (TOML; see examples/study/emoji.toml).
    plan: PathBuf,
    /// The participant's ID (letters, digits, _ and -); seeds their orders.
    #[arg(long)]
    participant: String,
    /// The sleeve's serial port; else the only USB serial port attached.
    #[arg(long, value_name = "PATH")]
    port: Option<PathBuf>,
    /// The session log (JSON lines); default `<participant>.jsonl` here.
    #[arg(long, value_name = "FILE")]
    log: Option<PathBuf>,
    /// Continue the session the log holds, with the same orders.
    #[arg(long)]
    resume: bool,
    /// The page's port on 127.0.0.1 (0: any free port).
    #[arg(long, default_value_t = 8037)]
    http_port: u16,
}

/// The trials the log already holds for `participant`, and whether acclimation is
/// done; refuses a log begun with another plan.
fn prior(
    path: &Path,
    plan: &Plan,
    participant: &str,
) -> anyhow::Result<(HashSet<(u32, u32)>, bool)> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let records = log::records(&text).with_context(|| path.display().to_string())?;
    let (mut done, mut acclimated) = (HashSet::new(), false);
    for r in records {
        match r {
            Record::Session(s)
                if s.scenarios != plan.names()
                    || s.seed != plan.seed
                    || s.rounds != plan.rounds
                    || s.participant != participant =>
            {
                bail!(
                    "{}: the log was begun by another plan or participant",
                    path.display()
                )
            }
            Record::Trial(t) => {
                done.insert((t.round, t.position));
            }
            Record::Event(e) if e.what == "acclimation" => acclimated = true,
            _ => {}
        }
    }
    Ok((done, acclimated))
}

/// Each scenario's playback length, ms; refuses a slot the sleeve lacks or will not play.
fn slot_lengths(port: &Path, sleeve: &mut Sleeve, plan: &Plan) -> anyhow::Result<Vec<u32>> {
    let mut lengths = Vec::new();
    for s in &plan.scenarios {
        let e = sleeve
            .slot(s.slot)
            .map_err(|e| anyhow!("{}: slot {} ({}): {e}", port.display(), s.slot, s.name))?;
        if !e.playable {
            bail!(
                "{}: slot {} ({}) is not playable",
                port.display(),
                s.slot,
                s.name
            );
        }
        lengths.push(e.playback_ms);
    }
    Ok(lengths)
}

/// Each stimulus once, unlabelled, so that the participant knows the range.
fn acclimate(
    ui: &mut Ui,
    sleeve: &mut Sleeve,
    log: &mut LogFile,
    lengths: &[u32],
    who: &str,
) -> anyhow::Result<()> {
    let plan = ui.plan;
    ui.phase = Phase::Acclimation;
    let order = plan.acclimation_order(who);
    ui.of = order.len() as u32;
    for (i, s) in order.into_iter().enumerate() {
        ui.position = i as u32 + 1;
        play(ui, sleeve, log, plan.scenarios[s].slot, lengths[s])?;
        ui.serve_for(Duration::from_millis(1500));
    }
    log.append(&Record::Event(EventRecord {
        what: "acclimation".into(),
        detail: String::new(),
    }))?;
    Ok(())
}

/// Runs `touchc study run`.
pub fn run(a: &RunArgs) -> anyhow::Result<()> {
    let plan = Plan::load(&a.plan)?;
    let who = &a.participant;
    if who.is_empty()
        || !who
            .chars()
            .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
    {
        return Err(crate::cli::report::usage(format!(
            "--participant {who:?}: use letters, digits, _ and -"
        )));
    }
    let log_path = a
        .log
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{who}.jsonl")));
    let exists = log_path.exists();
    if exists && !a.resume {
        return Err(crate::cli::report::usage(format!(
            "{}: the log exists; continue it with --resume",
            log_path.display()
        )));
    }
    let (done, acclimated) = if exists {
        prior(&log_path, &plan, who)?
    } else {
        (HashSet::new(), false)
    };
    let (port, mut sleeve) = open_sleeve(a.port.as_deref())?;
    let lengths = slot_lengths(&port, &mut sleeve, &plan)?;
    let server = Server::bind(a.http_port)
        .with_context(|| format!("cannot listen on 127.0.0.1:{}", a.http_port))?;
    let file = File::options()
        .create(true)
        .append(true)
        .open(&log_path)
        .with_context(|| log_path.display().to_string())?;
    let mut log = LogFile {
        path: log_path,
        file,
    };
    log.append(&Record::Session(Session {
        version: log::VERSION,
        participant: who.clone(),
        scenarios: plan.names(),
        seed: plan.seed,
        rounds: plan.rounds,
        repeats: plan.repeats,
        sam: plan.sam,
        started: now_s(),
        resumed: exists,
    }))?;
    eprintln!(
        "participant page: {} (sleeve on {})",
        server.url()?,
        port.display()
    );
    let mut ui = Ui {
        plan: &plan,
        server,
        phase: Phase::Intro,
        id: 0,
        round: 0,
        position: 0,
        of: 0,
        message: String::new(),
        started: false,
        answer: None,
        replay: false,
    };
    while !ui.started {
        ui.serve_for(Duration::from_millis(50));
    }
    if plan.acclimation && !acclimated {
        acclimate(&mut ui, &mut sleeve, &mut log, &lengths, who)?;
    }
    trials(&mut ui, &mut sleeve, &mut log, &done, &lengths, who)?;
    ui.phase = Phase::Done;
    log.append(&Record::Event(EventRecord {
        what: "done".into(),
        detail: String::new(),
    }))?;
    eprintln!("session complete: {}", log.path.display());
    ui.serve_for(Duration::from_secs(3));
    Ok(())
}

/// Every trial not yet in the log: play, then wait for the page's answer and log it.
fn trials(
    ui: &mut Ui,
    sleeve: &mut Sleeve,
    log: &mut LogFile,
    done: &HashSet<(u32, u32)>,
    lengths: &[u32],
    who: &str,
) -> anyhow::Result<()> {
    let plan = ui.plan;
    let all = plan.trials(who);
    let total = all.len();
    for (n, (round, position, s)) in all.into_iter().enumerate() {
        if done.contains(&(round, position)) {
            continue;
        }
        let sc = &plan.scenarios[s];
        ui.id += 1;
        (ui.round, ui.position) = (round, position);
        ui.of = if round > plan.rounds {
            plan.scenarios.len()
        } else {
            plan.scenarios.len() * plan.repeats as usize
        } as u32;
        ui.phase = Phase::Playing;
        let (start, end) = play(ui, sleeve, log, sc.slot, lengths[s])?;
        let mut plays = 1;
        ui.phase = if round > plan.rounds {
            Phase::Sam
        } else {
            Phase::Classify
        };
        let asked = Instant::now();
        let answer = loop {
            ui.serve_for(Duration::from_millis(20));
            if let Some(a) = ui.answer.take() {
                break a;
            }
            if std::mem::take(&mut ui.replay) {
                let phase = ui.phase;
                ui.phase = Phase::Playing;
                play(ui, sleeve, log, sc.slot, lengths[s])?;
                plays += 1;
                ui.phase = phase;
            }
        };
        let p = answer.p.map(|p| {
            let sum: f64 = p.iter().sum();
            p.iter().map(|v| v / sum).collect()
        });
        log.append(&Record::Trial(TrialRecord {
            participant: who.to_string(),
            round,
            position,
            stimulus: sc.name.clone(),
            slot: sc.slot,
            start_tick: start,
            end_tick: end,
            plays,
            p,
            valence: answer.valence,
            arousal: answer.arousal,
            response_s: asked.elapsed().as_secs_f64(),
        }))?;
        let heat = sleeve
            .status()
            .map(|s| s.heat_permille.iter().copied().max().unwrap_or(0));
        eprintln!(
            "trial {}/{total}: round {round} #{position} {} (slot {}), ticks {start}..{}, hottest coil {}",
            n + 1,
            sc.name,
            sc.slot,
            end.map_or("?".into(), |e| e.to_string()),
            heat.map_or("?".into(), |h| format!("{} %", h / 10))
        );
    }
    Ok(())
}
