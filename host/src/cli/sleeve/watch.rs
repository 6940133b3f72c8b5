//! `touchc sleeve status` and `touchc sleeve events`: what the sleeve does, once or
//! as it happens.

use std::io::Write;
use std::path::Path;
use std::time::{Duration, SystemTime};

use serde_json::json;
use touch_protocol::link::{Event, Gesture, Source, StreamStop};
use touchc_link::Stamped;

use super::{connect, describe, limit_name, source_json, unix_s, Link};
use crate::cli::report::usage;

pub(super) fn status(
    port: Option<&Path>,
    watch: bool,
    interval_ms: u64,
    as_json: bool,
) -> anyhow::Result<()> {
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

pub(super) fn events(
    port: Option<&Path>,
    count: Option<u64>,
    duration: Option<f64>,
) -> anyhow::Result<()> {
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
