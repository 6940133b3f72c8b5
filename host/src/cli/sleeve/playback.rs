//! `touchc sleeve play` and `touchc sleeve stop`.

use std::path::Path;
use std::time::SystemTime;

use serde_json::json;
use touch_protocol::link::Source;

use super::{connect, describe, source_json, unix_s, Link};

pub(super) fn play(port: Option<&Path>, slot: u8, as_json: bool) -> anyhow::Result<()> {
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

pub(super) fn stop(port: Option<&Path>, as_json: bool) -> anyhow::Result<()> {
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
