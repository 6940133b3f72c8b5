//! `touchc export` and `touchc import`, checked the way each format's own reader would
//! check the files: validators written here from the readers' rules (the MPEG-I
//! reference software's JSON loader, the Lofelt data model's validation, Core Haptics'
//! documented AHAP keys and limits, the bHaptics SDKs' `.tact` structure), never the
//! exporter's code. The signal each file carries is rebuilt here from the file alone
//! and compared with `touchc render --csv` (the player's output), on every shipped
//! stimulus and every slot of the emoji bank.

use std::path::{Path, PathBuf};

use serde_json::Value;
use touchc_model::layout::Layout;

use crate::bin::{ok, refused, s, stderr, touchc};

const FULL_SCALE_A: f64 = 1.0;
const EMOJI: [&str; 6] = [
    "attention",
    "calming",
    "gratitude",
    "happiness",
    "love",
    "sadness",
];

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn emoji(name: &str) -> PathBuf {
    repo().join("examples/emoji").join(format!("{name}.touch"))
}

fn bank() -> PathBuf {
    repo().join("examples/emoji/emoji.bank")
}

/// The player's output, per channel, amperes per 1 kHz tick, from `touchc render`.
fn rendered(file: &Path, slot: usize) -> [Vec<f64>; 8] {
    let out = touchc(&["render", s(file), "--csv", "--slot", &slot.to_string()]);
    ok(&out);
    let mut channels: [Vec<f64>; 8] = Default::default();
    for line in String::from_utf8(out.stdout).unwrap().lines().skip(1) {
        for (c, v) in line.split(',').skip(1).enumerate() {
            channels[c].push(v.parse().unwrap());
        }
    }
    channels
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// RMS and max of `a - b` over every tick of both (0 beyond the shorter), fractions
/// of the full scale.
fn error(a: &[Vec<f64>], b: &[Vec<f64>]) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for (x, y) in a.iter().zip(b) {
        for t in 0..x.len().max(y.len()) {
            let e = (x.get(t).copied().unwrap_or(0.0) - y.get(t).copied().unwrap_or(0.0))
                / FULL_SCALE_A;
            sum += e * e;
            max = max.max(e.abs());
            n += 1;
        }
    }
    ((sum / n as f64).sqrt(), max)
}

/// Linear interpolation through `points` (time, value), sorted, at 1 kHz for `ticks`.
fn sampled(points: &[(f64, f64)], ticks: usize) -> Vec<f64> {
    let mut k = 0;
    (0..ticks)
        .map(|t| {
            let t = t as f64;
            while k + 1 < points.len() && points[k + 1].0 <= t {
                k += 1;
            }
            let (t0, v0) = points[k];
            match points.get(k + 1) {
                Some(&(t1, v1)) if t > t0 => v0 + (v1 - v0) * (t - t0) / (t1 - t0),
                _ => v0,
            }
        })
        .collect()
}

// ---------------------------------------------------------------- MPEG-I HJIF

/// `touchc export FILE --to FORMAT EXTRA... -o OUT`, which must succeed.
fn export_ok(file: &Path, format: &str, extra: &[&str], out: &Path) {
    let mut args = vec!["export", s(file), "--to", format];
    args.extend_from_slice(extra);
    args.extend(["-o", s(out)]);
    ok(&touchc(&args));
}

/// The emoji as export cases: each file, slot 0.
fn emoji_cases() -> Vec<(PathBuf, usize)> {
    EMOJI.iter().map(|n| (emoji(n), 0)).collect()
}

/// The emoji files and every slot of the emoji bank.
fn emoji_and_bank_cases() -> Vec<(PathBuf, usize)> {
    let mut cases = emoji_cases();
    cases.extend((0..EMOJI.len()).map(|slot| (bank(), slot)));
    cases
}

/// Exports each `(file, slot)` of `cases` `--to format` into a fresh directory and
/// calls `check(output, file, slot, played)`: the `-o` path (a single-signal format's
/// files are its [`channel_file`]s) and the player's output from `touchc render`.
fn for_each_export(
    format: &str,
    cases: &[(PathBuf, usize)],
    mut check: impl FnMut(&Path, &Path, usize, &[Vec<f64>; 8]),
) {
    let dir = tempfile::tempdir().unwrap();
    for (k, (file, slot)) in cases.iter().enumerate() {
        let out = dir.path().join(format!("x{k}.{format}"));
        export_ok(file, format, &["--slot", &slot.to_string()], &out);
        check(&out, file, *slot, &rendered(file, *slot));
    }
}

/// Where `touchc export -o out` writes actuator `c`'s file of a single-signal format.
fn channel_file(out: &Path, c: usize) -> PathBuf {
    let ext = out.extension().unwrap().to_str().unwrap();
    out.with_extension(format!("ch{c}.{ext}"))
}

/// Exports `cases` `--to format`, rebuilds each actuator's current from the files
/// alone (`rebuild(output, channel, ticks)`, amperes per tick) and asserts that every
/// case is within the compile bounds of the player's output (0.5% RMS, 2% max of full
/// scale); prints the worst case's figures under `label`.
fn rebuilt_within_the_bounds(
    format: &str,
    label: &str,
    cases: &[(PathBuf, usize)],
    mut rebuild: impl FnMut(&Path, usize, usize) -> Vec<f64>,
) {
    let mut worst = (0.0f64, 0.0f64);
    for_each_export(format, cases, |out, file, slot, played| {
        let rebuilt: Vec<Vec<f64>> = (0..8).map(|c| rebuild(out, c, played[0].len())).collect();
        let (rms, max) = error(played, &rebuilt);
        assert!(
            rms <= 0.005 && max <= 0.02,
            "{} slot {slot}: {rms} {max}",
            file.display()
        );
        worst = (worst.0.max(rms), worst.1.max(max));
    });
    eprintln!(
        "{label} against the player: worst {:.3}% RMS / {:.3}% max of full scale",
        100.0 * worst.0,
        100.0 * worst.1
    );
}

fn int(v: &Value, key: &str, at: &str) -> i64 {
    v.get(key)
        .and_then(Value::as_i64)
        .unwrap_or_else(|| panic!("{at}: missing or invalid integer `{key}`"))
}

fn num(v: &Value, key: &str, at: &str) -> f64 {
    v.get(key)
        .and_then(Value::as_f64)
        .unwrap_or_else(|| panic!("{at}: missing or invalid number `{key}`"))
}

fn string<'a>(v: &'a Value, key: &str, at: &str) -> &'a str {
    v.get(key)
        .and_then(Value::as_str)
        .unwrap_or_else(|| panic!("{at}: missing or invalid string `{key}`"))
}

fn array<'a>(v: &'a Value, key: &str, at: &str) -> &'a Vec<Value> {
    v.get(key)
        .and_then(Value::as_array)
        .unwrap_or_else(|| panic!("{at}: missing or invalid array `{key}`"))
}

/// The reference software's loader and conformance rules, for what an HJIF of
/// curves uses. Returns each channel's keyframes (tick, amplitude) by channel id.
fn validate_hjif(doc: &Value) -> Vec<(i64, Vec<(f64, f64)>)> {
    let at = "hjif";
    // Required top-level members.
    let version = string(doc, "version", at);
    let profile = string(doc, "profile", at);
    let level = int(doc, "level", at);
    let date = string(doc, "date", at);
    string(doc, "description", at);
    let timescale = int(doc, "timescale", at);
    let perceptions = array(doc, "perceptions", at);
    let avatars = array(doc, "avatars", at);
    array(doc, "syncs", at);
    // Version: YYYY or YYYY-N, year >= 2023, amendment > 0.
    let (year, amendment) = version.split_once('-').unwrap_or((version, ""));
    assert!(
        year.len() == 4 && year.chars().all(|c| c.is_ascii_digit()),
        "{version}"
    );
    assert!(year.parse::<u32>().unwrap() >= 2023, "{version}");
    if !amendment.is_empty() {
        assert!(amendment.len() == 1 && amendment.parse::<u32>().unwrap() > 0);
    }
    assert!(
        profile == "Main" || profile == "Simple Parametric",
        "{profile}"
    );
    assert!(level == 1 || level == 2, "level {level}");
    // ISO 8601: a year, optionally -MM and -DD.
    let d: Vec<&str> = date.split('-').collect();
    assert!(
        d[0].len() == 4 && d.iter().all(|p| p.chars().all(|c| c.is_ascii_digit())),
        "{date}"
    );
    if profile == "Main" {
        assert!(timescale > 0 && timescale <= 48_000, "{timescale}");
    } else {
        assert_eq!(timescale, 1000);
    }
    assert_eq!(timescale, 1000, "positions are read as ms below");
    let mut avatar_ids = Vec::new();
    for a in avatars {
        let id = int(a, "id", "avatar");
        int(a, "lod", "avatar");
        let kind = string(a, "type", "avatar");
        assert!(["Vibration", "Pressure", "Temperature", "Custom"].contains(&kind));
        assert_ne!(id, 0, "avatar id 0 is reserved");
        assert!(!avatar_ids.contains(&id), "avatar id {id} not unique");
        avatar_ids.push(id);
    }
    let modalities = [
        "Other",
        "Pressure",
        "Acceleration",
        "Velocity",
        "Position",
        "Temperature",
        "Vibration",
        "Vibrotactile",
        "Water",
        "Wind",
        "Kinesthetic",
        "Force",
        "Vibrotactile Texture",
        "Texture",
        "Stiffness",
        "Friction",
        "Electrotactile",
    ];
    let mut curves = Vec::new();
    let mut perception_ids = Vec::new();
    for p in perceptions {
        let at = "perception";
        let id = int(p, "id", at);
        assert!(!perception_ids.contains(&id));
        perception_ids.push(id);
        let avatar = int(p, "avatar_id", at);
        assert!(
            avatar == 0 || avatar_ids.contains(&avatar),
            "avatar {avatar}"
        );
        string(p, "description", at);
        assert!(modalities.contains(&string(p, "perception_modality", at)));
        array(p, "effect_library", at);
        assert!(
            p.get("effect_semantic_scheme").is_none(),
            "the loader refuses any scheme"
        );
        let mut device_ids = Vec::new();
        for dev in p
            .get("reference_devices")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            let id = int(dev, "id", "reference device");
            string(dev, "name", "reference device");
            assert!(!device_ids.contains(&id));
            device_ids.push(id);
            let f = |k| dev.get(k).and_then(Value::as_f64);
            if let (Some(lo), Some(hi)) = (f("minimum_frequency"), f("maximum_frequency")) {
                assert!(hi >= lo);
            }
            if let Some(r) = f("resonance_frequency") {
                assert!(f("minimum_frequency").is_none_or(|lo| r >= lo));
                assert!(f("maximum_frequency").is_none_or(|hi| r <= hi));
            }
            if let Some(t) = dev.get("type") {
                assert!(["Unknown", "LRA", "VCA", "ERM", "Piezo"].contains(&t.as_str().unwrap()));
            }
        }
        let channels = array(p, "channels", at);
        assert!(channels.len() <= if level == 1 { 128 } else { 65_536 });
        let mut channel_ids = Vec::new();
        for ch in channels {
            let at = "channel";
            let id = int(ch, "id", at);
            assert!(!channel_ids.contains(&id), "channel id {id} not unique");
            channel_ids.push(id);
            string(ch, "description", at);
            num(ch, "gain", at);
            num(ch, "mixing_coefficient", at);
            assert!(ch.get("body_part_mask").and_then(Value::as_u64).is_some());
            if let Some(dev) = ch.get("reference_device_id") {
                assert!(device_ids.contains(&dev.as_i64().unwrap()));
            }
            let vector = |v: &Value| -> [i64; 3] {
                ["X", "Y", "Z"].map(|k| {
                    let x = int(v, k, "vector");
                    assert!((-128..=127).contains(&x));
                    x
                })
            };
            match (ch.get("actuator_resolution"), ch.get("actuator_target")) {
                (Some(res), targets) => {
                    let res = vector(res);
                    assert!(res.iter().all(|&r| r >= 0));
                    for t in targets.and_then(Value::as_array).into_iter().flatten() {
                        let t = vector(t);
                        assert!((0..3).all(|i| t[i] >= 0 && t[i] <= res[i]), "{t:?} {res:?}");
                    }
                }
                (None, Some(_)) => panic!("actuator target without a resolution"),
                (None, None) => {}
            }
            let bands = array(ch, "bands", at);
            assert!(bands.len() <= if level == 1 { 7 } else { 65_536 });
            let mut points = Vec::new();
            for b in bands {
                let at = "band";
                let kind = string(b, "band_type", at);
                assert!(["WaveletWave", "VectorialWave", "Curve", "Transient"].contains(&kind));
                if let Some(c) = b.get("curve_type") {
                    assert_eq!(kind, "Curve", "curve type on a {kind} band");
                    assert!(["Unknown", "Cubic", "Linear", "Akima", "Bezier", "Bspline"]
                        .contains(&c.as_str().unwrap()));
                }
                let lo = int(b, "lower_frequency_limit", at);
                let hi = int(b, "upper_frequency_limit", at);
                assert!(hi >= lo);
                for e in array(b, "effects", at) {
                    let kind = string(e, "effect_type", "effect");
                    assert!(["Basis", "Reference", "Composite"].contains(&kind));
                    let position = int(e, "position", "effect");
                    for k in e
                        .get("keyframes")
                        .and_then(Value::as_array)
                        .into_iter()
                        .flatten()
                    {
                        let rel = int(k, "relative_position", "keyframe");
                        let a = num(k, "amplitude_modulation", "keyframe");
                        assert!((-1.0..=1.0).contains(&a), "amplitude {a}");
                        points.push(((position + rel) as f64, a));
                    }
                }
            }
            assert!(
                points.windows(2).all(|w| w[0].0 < w[1].0),
                "keyframes in time order"
            );
            curves.push((id, points));
        }
    }
    curves
}

#[test]
fn hjif_follows_the_reference_loader_carries_the_layout_and_meets_the_bounds() {
    rebuilt_within_the_bounds("hjif", "hjif", &emoji_and_bank_cases(), |out, c, ticks| {
        let doc = json(out);
        let curves = validate_hjif(&doc);
        // The sleeve: one pressure perception, eight channels in order, on the forearm
        // mask at their grid places.
        let p = &doc["perceptions"][0];
        assert_eq!(p["perception_modality"], "Pressure");
        assert_eq!(curves.len(), 8);
        let ch = &p["channels"][c];
        assert_eq!(ch["id"], c as i64);
        // A forearm bit of the mask (right 0x1000 or left 0x2000).
        assert!(ch["body_part_mask"].as_u64().unwrap() & 0x3000 != 0);
        assert_eq!(ch["actuator_target"][0]["X"], (c % 4) as i64);
        assert_eq!(ch["actuator_target"][0]["Y"], (c / 4) as i64);
        assert!(doc["description"]
            .as_str()
            .unwrap()
            .contains(&format!("{:08x}", touch_protocol::layout::SLEEVE_HASH)));
        sampled(&curves[c].1, ticks)
            .into_iter()
            .map(|a| a * FULL_SCALE_A)
            .collect()
    });
}

#[test]
fn an_hjif_round_trip_plays_within_the_compile_bounds_of_the_original() {
    let dir = tempfile::tempdir().unwrap();
    for name in EMOJI {
        let hjif = dir.path().join(format!("{name}.hjif"));
        let back = dir.path().join(format!("{name}.touch"));
        export_ok(&emoji(name), "hjif", &[], &hjif);
        ok(&touchc(&["import", s(&hjif), "-o", s(&back)]));
        let (rms, max) = error(&rendered(&emoji(name), 0), &rendered(&back, 0));
        eprintln!(
            "{name}: round trip {:.3}% RMS / {:.3}% max of full scale, {} -> {} bytes",
            100.0 * rms,
            100.0 * max,
            std::fs::metadata(emoji(name)).unwrap().len(),
            std::fs::metadata(&back).unwrap().len()
        );
        assert!(rms <= 0.005 && max <= 0.02, "{name}: {rms} {max}");
    }
}

#[test]
fn import_refuses_a_file_for_another_layout_and_what_is_not_hjif() {
    let dir = tempfile::tempdir().unwrap();
    let hjif = dir.path().join("love.hjif");
    export_ok(&emoji("love"), "hjif", &[], &hjif);
    let other = dir.path().join("other.toml");
    std::fs::write(&other, moved_layout()).unwrap();
    let back = dir.path().join("back.touch");
    let err = refused(&touchc(&[
        "import",
        s(&hjif),
        "--layout",
        s(&other),
        "-o",
        s(&back),
    ]));
    assert!(err.contains("layout") && err.contains("love.hjif"), "{err}");
    assert!(!back.exists());
    // A keyframe a day away: refused, not sampled into gigabytes.
    let far = dir.path().join("far.hjif");
    let text = std::fs::read_to_string(&hjif).unwrap();
    let text = text.replacen(
        "\"relative_position\":0,",
        "\"relative_position\":86400000,",
        1,
    );
    std::fs::write(&far, text).unwrap();
    let err = refused(&touchc(&["import", s(&far), "-o", s(&back)]));
    assert!(
        err.contains("far.hjif") && err.contains("86400000"),
        "{err}"
    );
    assert!(!back.exists());
    let junk = dir.path().join("junk.hjif");
    std::fs::write(&junk, b"{\"version\": \"2023\"}").unwrap();
    let err = refused(&touchc(&["import", s(&junk), "-o", s(&back)]));
    assert!(err.contains("junk.hjif") && err.contains("HJIF"), "{err}");
    assert!(!back.exists());
}

/// The paper's layout with row 1 moved 2 mm: another geometry.
fn moved_layout() -> String {
    let text = Layout::paper().to_toml_string().unwrap();
    let text = text.replace("y_mm = 50.0", "y_mm = 52.0");
    assert!(
        Layout::from_toml_str(&text, "moved")
            .unwrap()
            .geometry_hash()
            != touch_protocol::layout::SLEEVE_HASH
    );
    text
}

// ---------------------------------------------------------------- Lofelt .haptic

/// The Lofelt data model's V1 validation: version major 1; a non-empty amplitude
/// envelope, amplitudes in 0..1, times non-decreasing; emphasis (if any) in 0..1 and
/// not below its breakpoint. Returns the breakpoints (ms, amplitude).
fn validate_haptic(doc: &Value) -> Vec<(f64, f64)> {
    assert_eq!(doc["version"]["major"], 1, "only V1 files are read as V1");
    let amplitude = doc["signals"]["continuous"]["envelopes"]["amplitude"]
        .as_array()
        .expect("signals.continuous.envelopes.amplitude");
    assert!(amplitude.len() >= 2, "at least two breakpoints");
    let mut last = 0.0;
    let mut points = Vec::new();
    for bp in amplitude {
        let t = num(bp, "time", "breakpoint");
        let a = num(bp, "amplitude", "breakpoint");
        assert!((0.0..=1.0).contains(&a), "amplitude {a}");
        assert!(t >= last, "time {t} after {last}");
        last = t;
        if let Some(e) = bp.get("emphasis") {
            let ea = num(e, "amplitude", "emphasis");
            let ef = num(e, "frequency", "emphasis");
            assert!((0.0..=1.0).contains(&ea) && (0.0..=1.0).contains(&ef) && ea >= a);
        }
        points.push((t * 1000.0, a));
    }
    if let Some(freq) = doc["signals"]["continuous"]["envelopes"].get("frequency") {
        for f in freq.as_array().unwrap() {
            assert!((0.0..=1.0).contains(&num(f, "frequency", "frequency")));
        }
    }
    points
}

#[test]
fn haptic_files_follow_the_lofelt_data_model_one_per_actuator() {
    rebuilt_within_the_bounds(
        "haptic",
        ".haptic (amplitude = (I/FS + 1)/2)",
        &emoji_cases(),
        |out, c, ticks| {
            let points = validate_haptic(&json(&channel_file(out, c)));
            // Times are seconds as f32 in the SDK: round to the tick.
            let points: Vec<(f64, f64)> = points.iter().map(|&(t, a)| (t.round(), a)).collect();
            sampled(&points, ticks)
                .into_iter()
                .map(|a| (2.0 * a - 1.0) * FULL_SCALE_A)
                .collect()
        },
    );
}

#[test]
fn one_haptic_file_of_a_bank_slot_its_channel_or_its_mix() {
    let dir = tempfile::tempdir().unwrap();
    let played = rendered(&bank(), 4);
    let mix = dir.path().join("mix.haptic");
    export_ok(&bank(), "haptic", &["--slot", "4", "--mix"], &mix);
    let one = dir.path().join("one.haptic");
    export_ok(&bank(), "haptic", &["--slot", "4", "--channel", "5"], &one);
    let ticks = played[0].len();
    let most_pressed: Vec<f64> = (0..ticks)
        .map(|t| played.iter().map(|c| c[t]).fold(f64::MIN, f64::max))
        .collect();
    for (file, want) in [(&mix, most_pressed), (&one, played[5].clone())] {
        let points = validate_haptic(&json(file));
        let got: Vec<f64> = sampled(&points, ticks)
            .into_iter()
            .map(|a| 2.0 * a - 1.0)
            .collect();
        let (rms, max) = error(&[want], &[got]);
        assert!(
            rms <= 0.005 && max <= 0.02,
            "{}: {rms} {max}",
            file.display()
        );
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

// ---------------------------------------------------------------- Apple AHAP

/// Core Haptics' AHAP keys and limits: `Version` 1.0; `Pattern` entries each one
/// `Event` or `ParameterCurve`; events of a known type at non-negative times,
/// continuous ones at most 30 s; parameter values 0..1; a curve of a dynamic
/// parameter holds 1 to 16 control points, times relative to the curve and
/// non-decreasing. Returns the intensity control points (ms, value) on one time line,
/// and the end of the last event (ms).
fn validate_ahap(doc: &Value) -> (Vec<(f64, f64)>, f64) {
    assert_eq!(doc["Version"].as_f64(), Some(1.0));
    let mut points: Vec<(f64, f64)> = Vec::new();
    let mut end = 0.0f64;
    let mut covered = 0.0f64;
    for entry in doc["Pattern"].as_array().expect("Pattern") {
        let obj = entry.as_object().unwrap();
        assert_eq!(obj.len(), 1, "one of Event, ParameterCurve, Parameter");
        if let Some(e) = obj.get("Event") {
            let t = num(e, "Time", "Event");
            assert!(t >= 0.0);
            let kind = string(e, "EventType", "Event");
            assert!([
                "HapticTransient",
                "HapticContinuous",
                "AudioContinuous",
                "AudioCustom"
            ]
            .contains(&kind));
            if kind == "HapticContinuous" {
                let d = num(e, "EventDuration", "Event");
                assert!(d > 0.0 && d <= 30.0, "duration {d}");
                assert!(t <= covered + 1e-9, "events leave a gap at {covered}");
                covered = covered.max(t + d);
                end = end.max(1000.0 * (t + d));
            }
            for p in array(e, "EventParameters", "Event") {
                let id = string(p, "ParameterID", "EventParameter");
                assert!([
                    "HapticIntensity",
                    "HapticSharpness",
                    "AttackTime",
                    "DecayTime",
                    "ReleaseTime",
                    "Sustained"
                ]
                .contains(&id));
                assert!((0.0..=1.0).contains(&num(p, "ParameterValue", "EventParameter")));
            }
        } else if let Some(c) = obj.get("ParameterCurve") {
            let id = string(c, "ParameterID", "ParameterCurve");
            assert!([
                "HapticIntensityControl",
                "HapticSharpnessControl",
                "HapticAttackTimeControl",
                "HapticDecayTimeControl",
                "HapticReleaseTimeControl"
            ]
            .contains(&id));
            let t0 = num(c, "Time", "ParameterCurve");
            assert!(t0 >= 0.0);
            let cps = array(c, "ParameterCurveControlPoints", "ParameterCurve");
            assert!(
                (1..=16).contains(&cps.len()),
                "{} control points",
                cps.len()
            );
            let mut last = 0.0;
            for cp in cps {
                let t = num(cp, "Time", "control point");
                let v = num(cp, "ParameterValue", "control point");
                assert!(t >= last && (0.0..=1.0).contains(&v));
                last = t;
                if id == "HapticIntensityControl" {
                    let ms = ((t0 + t) * 1000.0).round();
                    match points.last() {
                        // A chained curve starts where the last one ended.
                        Some(&(pt, pv)) if pt == ms => assert!((pv - v).abs() < 1e-9),
                        Some(&(pt, _)) => {
                            assert!(ms > pt);
                            points.push((ms, v))
                        }
                        None => points.push((ms, v)),
                    }
                }
            }
        } else {
            panic!("unknown pattern entry {obj:?}");
        }
    }
    (points, end)
}

#[test]
fn ahap_files_follow_core_haptics_limits_and_carry_each_actuator() {
    rebuilt_within_the_bounds(
        "ahap",
        "AHAP (intensity = sqrt((I/FS + 1)/2))",
        &emoji_cases(),
        |out, c, ticks| {
            let (points, end) = validate_ahap(&json(&channel_file(out, c)));
            assert!(
                end + 1.0 >= points.last().unwrap().0,
                "curve outlives events"
            );
            // Intensity is the square root of the amplitude (Lofelt's mapping).
            sampled(&points, ticks)
                .into_iter()
                .map(|i| (2.0 * i * i - 1.0) * FULL_SCALE_A)
                .collect()
        },
    );
}

#[test]
fn a_long_ahap_chains_its_events_and_curves() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.touch");
    std::fs::write(&long, crate::stimuli::long("long", 75)).unwrap();
    let out = dir.path().join("long.ahap");
    export_ok(&long, "ahap", &["--channel", "0"], &out);
    let doc = json(&out);
    let (points, end) = validate_ahap(&doc);
    let events = doc["Pattern"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e.get("Event").is_some())
        .count();
    assert!(events >= 3, "{events} events for {end} ms");
    assert!(end >= 75_000.0);
    assert!(points.len() >= 2);
}

// ---------------------------------------------------------------- bHaptics .tact

/// The structure the bHaptics SDKs read from a `.tact`: `project` with `tracks` of
/// `effects` (integer `startTime`, `offsetTime`, `modes` by device position) and a
/// `layout` (`type`, `layouts` of motors with `index`, `x`, `y`); a mode's `mode` is
/// `DOT_MODE` or `PATH_MODE`, its `dotMode` has `dotConnected` and `feedback` of
/// `startTime` < `endTime`, a `playbackType` and a `pointList` of motor `index` and
/// `intensity` (0..1); `durationMillis`, `intervalMillis`, `size` are integers.
/// Returns each motor's intensity per 1 ms tick.
fn validate_tact(doc: &Value) -> [Vec<f64>; 6] {
    let duration = int(doc, "durationMillis", "tact") as usize;
    assert!(int(doc, "intervalMillis", "tact") > 0);
    int(doc, "size", "tact");
    let project = &doc["project"];
    let layout = &project["layout"];
    string(layout, "type", "layout");
    let motors = layout["layouts"]["ForearmL"]
        .as_array()
        .expect("ForearmL layout");
    assert_eq!(motors.len(), 6);
    for m in motors {
        let i = int(m, "index", "motor");
        assert!((0..6).contains(&i));
        let (x, y) = (num(m, "x", "motor"), num(m, "y", "motor"));
        assert!((0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y));
    }
    let positions = [
        "VestFront",
        "VestBack",
        "Head",
        "ForearmL",
        "ForearmR",
        "HandL",
        "HandR",
        "FootL",
        "FootR",
        "GloveL",
        "GloveR",
    ];
    let mut motor: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; duration]);
    for track in array(project, "tracks", "project") {
        for effect in array(track, "effects", "track") {
            let start = int(effect, "startTime", "effect");
            let offset = int(effect, "offsetTime", "effect");
            assert!(start >= 0 && offset > 0);
            for (position, mode) in effect["modes"].as_object().expect("modes") {
                assert!(positions.contains(&position.as_str()), "{position}");
                let kind = string(mode, "mode", "mode");
                assert!(kind == "DOT_MODE" || kind == "PATH_MODE");
                let dot = &mode["dotMode"];
                assert!(dot["dotConnected"].is_boolean());
                assert!(mode["pathMode"].is_object());
                for fb in array(dot, "feedback", "dotMode") {
                    let (s0, s1) = (
                        int(fb, "startTime", "feedback"),
                        int(fb, "endTime", "feedback"),
                    );
                    assert!(0 <= s0 && s0 < s1 && s1 <= offset, "{s0}..{s1}");
                    assert!(
                        ["NONE", "FADE_IN", "FADE_OUT", "FADE_IN_OUT"].contains(&string(
                            fb,
                            "playbackType",
                            "feedback"
                        ))
                    );
                    for p in array(fb, "pointList", "feedback") {
                        let i = int(p, "index", "point") as usize;
                        let v = num(p, "intensity", "point");
                        assert!(i < 6 && (0.0..=1.0).contains(&v));
                        // Whole percent: the motors' 0-100 scale.
                        assert!((v * 100.0 - (v * 100.0).round()).abs() < 1e-9);
                        motor[i][(start + s0) as usize..(start + s1) as usize].fill(v);
                    }
                }
            }
        }
    }
    motor
}

#[test]
fn tact_files_follow_the_sdk_structure_and_their_loss_is_measured() {
    // The documented weights on the paper's layout: motors 0-2 along row 0 from the
    // elbow, 3-5 along row 1; each motor's share of each column.
    let share = [
        [1.0, 1.0 / 3.0, 0.0, 0.0],
        [0.0, 2.0 / 3.0, 2.0 / 3.0, 0.0],
        [0.0, 0.0, 1.0 / 3.0, 1.0],
    ];
    for_each_export(
        "tact",
        &emoji_and_bank_cases(),
        |out, file, slot, played| {
            let motors = validate_tact(&json(out));
            // What each motor should play: its weighted mean of the amplitudes it is fed.
            let want: Vec<Vec<f64>> = (0..6)
                .map(|m| {
                    let (row, col) = (m / 3, m % 3);
                    let total: f64 = share[col].iter().sum();
                    (0..played[0].len())
                        .map(|t| {
                            (0..4)
                                .map(|c| share[col][c] * (played[row * 4 + c][t] + 1.0) / 2.0)
                                .sum::<f64>()
                                / total
                        })
                        .collect()
                })
                .collect();
            // Each 20 ms frame plays the mean of its mix over the frame, to a whole percent.
            let interval = 20;
            for (m, (want, got)) in want.iter().zip(&motors).enumerate() {
                for (k, frame) in want.chunks(interval).enumerate() {
                    let mean = frame.iter().sum::<f64>() / frame.len() as f64;
                    for (j, &v) in got[k * interval..k * interval + frame.len()]
                        .iter()
                        .enumerate()
                    {
                        assert!(
                            (v - mean).abs() <= 0.005 + 1e-6,
                            "motor {m} tick {}: {v} for a frame mean of {mean}",
                            k * interval + j
                        );
                    }
                }
            }
            let (rms, max) = error(&want, &motors);
            eprintln!(
            "{} slot {slot}: .tact motors against their mix {:.2}% RMS / {:.2}% max of amplitude (20 ms frames, whole percent)",
            file.display(),
            100.0 * rms,
            100.0 * max
        );
        },
    );
}

// ---------------------------------------------------------------- the command line

#[test]
fn every_shipped_recording_compiled_exports_to_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for rec in ["stroke", "squeeze", "tap_pat", "combination"] {
        let touch = dir.path().join(format!("{rec}.touch"));
        ok(&touchc(&[
            "compile",
            s(&repo().join(format!("examples/{rec}.npy"))),
            "-o",
            s(&touch),
        ]));
        for to in ["hjif", "haptic", "ahap", "tact"] {
            let out = touchc(&["export", s(&touch), "--to", to]);
            ok(&out);
            let line = crate::bin::stderr(&out);
            assert!(
                line.contains("bytes") && line.contains("B/s") && line.contains("% RMS"),
                "{line}"
            );
            eprint!("{line}");
        }
        let hjif = json(&dir.path().join(format!("{rec}.hjif")));
        validate_hjif(&hjif);
        for c in 0..8 {
            validate_haptic(&json(&dir.path().join(format!("{rec}.ch{c}.haptic"))));
            validate_ahap(&json(&dir.path().join(format!("{rec}.ch{c}.ahap"))));
        }
        validate_tact(&json(&dir.path().join(format!("{rec}.tact"))));
    }
}

#[test]
fn export_and_import_read_standard_input_and_write_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let piped = |args: &[&str], stdin: &Path| -> Vec<u8> {
        let out = crate::bin::command()
            .args(args)
            .stdin(std::fs::File::open(stdin).unwrap())
            .output()
            .unwrap();
        ok(&out);
        out.stdout
    };
    let tact = dir.path().join("love.tact");
    export_ok(&emoji("love"), "tact", &[], &tact);
    assert_eq!(
        piped(&["export", "-", "--to", "tact", "-o", "-"], &emoji("love")),
        std::fs::read(&tact).unwrap()
    );
    // From standard input, a stimulus is named as `compile` names one: "stdin".
    let hjif = dir.path().join("love.hjif");
    export_ok(&emoji("love"), "hjif", &[], &hjif);
    let back = dir.path().join("back.touch");
    ok(&touchc(&[
        "import",
        s(&hjif),
        "--name",
        "stdin",
        "-o",
        s(&back),
    ]));
    assert_eq!(
        piped(&["import", "-", "-o", "-"], &hjif),
        std::fs::read(&back).unwrap()
    );
}

#[test]
fn a_missing_slot_or_another_layout_is_refused_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.hjif");
    let r = touchc(&[
        "export",
        s(&bank()),
        "--slot",
        "6",
        "--to",
        "hjif",
        "-o",
        s(&out),
    ]);
    let err = refused(&r);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        err.contains("emoji.bank") && err.contains("slot 6"),
        "{err}"
    );
    assert!(!out.exists());
    let other = dir.path().join("other.toml");
    std::fs::write(&other, moved_layout()).unwrap();
    let r = touchc(&[
        "export",
        s(&emoji("love")),
        "--to",
        "hjif",
        "--layout",
        s(&other),
        "-o",
        s(&out),
    ]);
    let err = refused(&r);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        err.contains("love.touch") && err.contains("paper-2x4"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only the layout"
    );
}

#[test]
fn a_stimulus_longer_than_an_hour_is_refused_before_it_is_played() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.touch");
    std::fs::write(&long, crate::stimuli::long("long", 3601)).unwrap();
    let out = dir.path().join("long.hjif");
    let r = touchc(&["export", s(&long), "--to", "hjif", "-o", s(&out)]);
    let err = refused(&r);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        err.contains("long.touch") && err.contains("3601 s"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn usage_mistakes_exit_2_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.hjif");
    let love = emoji("love");
    for args in [
        vec![
            "export",
            s(&love),
            "--to",
            "hjif",
            "--channel",
            "2",
            "-o",
            s(&out),
        ],
        vec![
            "export",
            s(&love),
            "--to",
            "ahap",
            "--channel",
            "8",
            "-o",
            s(&out),
        ],
        vec!["export", s(&love), "--to", "haptic", "-o", "-"],
        vec!["export", s(&love), "--to", "wav", "-o", s(&out)],
    ] {
        let r = touchc(&args);
        refused(&r);
        assert_eq!(r.status.code(), Some(2), "{args:?}");
    }
    // No output over the input: the stimulus itself, named as the output.
    let copy = dir.path().join("love.touch");
    std::fs::copy(&love, &copy).unwrap();
    let r = touchc(&["export", s(&copy), "--to", "tact", "-o", s(&copy)]);
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(std::fs::read(&copy).unwrap(), std::fs::read(&love).unwrap());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn an_hjif_reference_device_carries_the_resonance_the_maker_gives() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("love.hjif");
    let device = |doc: &Value| doc["perceptions"][0]["reference_devices"][0].clone();

    export_ok(&emoji("love"), "hjif", &[], &out);
    let plain = json(&out);
    validate_hjif(&plain);
    assert!(device(&plain).get("resonance_frequency").is_none());

    std::fs::remove_file(&out).unwrap();
    export_ok(&emoji("love"), "hjif", &["--resonance-hz", "212.5"], &out);
    let given = json(&out);
    validate_hjif(&given);
    assert_eq!(device(&given)["resonance_frequency"], 212.5);

    // Out of range, not a number, or a format without a device: usage, and no file.
    std::fs::remove_file(&out).unwrap();
    for (to, hz) in [
        ("hjif", "0"),
        ("hjif", "NaN"),
        ("hjif", "1e9"),
        ("ahap", "200"),
    ] {
        let run = touchc(&[
            "export",
            s(&emoji("love")),
            "--to",
            to,
            "--resonance-hz",
            hz,
            "-o",
            s(&out),
        ]);
        assert_eq!(run.status.code(), Some(2), "{to} {hz}: {}", stderr(&run));
        assert!(stderr(&run).contains("--resonance-hz"), "{}", stderr(&run));
        assert!(!out.exists());
    }
}
