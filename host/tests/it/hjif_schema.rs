//! Every `.hjif` that `touchc export` writes meets MPEG's JSON schema for the format
//! (MPEGGroup/HapticJSONSchemas, `Specifications/MPEG_haptics*.schema.json`): its
//! required members, minimums, maximums, enums and the version's pattern, pinned here as
//! a table of our own (the schema is not copied into the repository) and checked on
//! the exports of every shipped emoji and of extreme stimuli.

use crate::bin::{s, stderr};
use crate::stimuli;

use serde_json::Value;

/// What one schema property requires of every value at a path.
#[derive(Debug, Clone, Copy)]
enum Rule {
    /// An integer in `min..=max`.
    Int(i64, i64),
    /// A number in `min..=max`.
    Num(f64, f64),
    /// One of these strings.
    Enum(&'static [&'static str]),
    /// A string.
    Str,
    /// An array of at least this many items.
    Array(usize),
    /// An object with these members.
    Required(&'static [&'static str]),
}

use Rule::{Array, Enum, Int, Num, Required, Str};

const U32: i64 = 4_294_967_295;
const ANY: i64 = i64::MAX;

/// The schema's constraints on the members `touchc` writes, by path (`[]`: every item
/// of an array). Read from the schema files of MPEGGroup/HapticJSONSchemas (first
/// commit, e3b9aa6); a member the exporter does not write is listed where the schema
/// constrains it, so that writing it later is checked too.
const RULES: &[(&str, Rule)] = &[
    (
        "",
        Required(&[
            "version",
            "profile",
            "level",
            "date",
            "description",
            "avatars",
            "perceptions",
        ]),
    ),
    ("version", Str),
    ("profile", Str),
    ("level", Int(0, ANY)),
    ("date", Str),
    ("description", Str),
    ("timescale", Int(1, ANY)),
    ("avatars", Array(0)),
    ("avatars[]", Required(&["id", "lod", "type"])),
    ("avatars[].id", Int(1, ANY)),
    ("avatars[].lod", Int(0, ANY)),
    (
        "avatars[].type",
        Enum(&["Vibration", "Pressure", "Temperature", "Custom"]),
    ),
    ("syncs[]", Required(&["timestamp"])),
    ("syncs[].timestamp", Int(0, ANY)),
    ("syncs[].timescale", Int(1, ANY)),
    ("perceptions", Array(1)),
    (
        "perceptions[]",
        Required(&[
            "id",
            "perception_modality",
            "description",
            "avatar_id",
            "effect_library",
            "channels",
        ]),
    ),
    ("perceptions[].id", Int(0, ANY)),
    (
        "perceptions[].perception_modality",
        Enum(&[
            "Pressure",
            "Acceleration",
            "Velocity",
            "Position",
            "Temperature",
            "Vibrotactile",
            "Water",
            "Wind",
            "Force",
            "Electrotactile",
            "Vibrotactile Texture",
            "Stiffness",
            "Friction",
            "Humidity",
            "User-defined Temporal",
            "User-defined Spatial",
            "Other",
        ]),
    ),
    ("perceptions[].description", Str),
    ("perceptions[].priority", Int(0, ANY)),
    ("perceptions[].avatar_id", Int(0, ANY)),
    ("perceptions[].effect_library", Array(0)),
    (
        "perceptions[].reference_devices[]",
        Required(&["id", "name"]),
    ),
    ("perceptions[].reference_devices[].id", Int(1, ANY)),
    ("perceptions[].reference_devices[].name", Str),
    (
        "perceptions[].reference_devices[].body_part_mask",
        Int(0, U32),
    ),
    (
        "perceptions[].reference_devices[].maximum_frequency",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].minimum_frequency",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].resonance_frequency",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].maximum_amplitude",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].impedance",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].maximum_voltage",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].maximum_current",
        Num(0.0, f64::MAX),
    ),
    (
        "perceptions[].reference_devices[].type",
        Enum(&["LRA", "VCA", "ERM", "Piezo", "Unknown"]),
    ),
    ("perceptions[].channels", Array(1)),
    (
        "perceptions[].channels[]",
        Required(&["id", "description", "gain", "mixing_coefficient", "bands"]),
    ),
    ("perceptions[].channels[].id", Int(0, ANY)),
    ("perceptions[].channels[].description", Str),
    ("perceptions[].channels[].priority", Int(0, ANY)),
    ("perceptions[].channels[].reference_device_id", Int(0, ANY)),
    ("perceptions[].channels[].gain", Num(0.0, f64::MAX)),
    (
        "perceptions[].channels[].mixing_coefficient",
        Num(0.0, f64::MAX),
    ),
    ("perceptions[].channels[].body_part_mask", Int(0, U32)),
    (
        "perceptions[].channels[].body_part_target[]",
        Enum(&[
            "Unknown",
            "All",
            "Upper",
            "Lower",
            "Right",
            "Left",
            "Front",
            "Back",
            "Arm",
            "Head",
            "Chest",
            "Waist",
            "Leg",
            "Upper-arm",
            "Forearm",
            "Hand",
            "Crane",
            "Neck",
            "Thigh",
            "Calf",
            "Foot",
            "Palm",
            "Finger",
            "Sole",
            "Toe",
            "Thumb",
            "Index",
            "Middle",
            "Ring",
            "Pinky",
            "Hallux",
            "Index-Toe",
            "Middle-Toe",
            "Ring-Toe",
            "Pinky-Toe",
            "First Phalanx",
            "Second Phalanx",
            "Third Phalanx",
            "Minus",
            "Plus",
        ]),
    ),
    (
        "perceptions[].channels[].actuator_resolution",
        Required(&["X", "Y", "Z"]),
    ),
    (
        "perceptions[].channels[].actuator_resolution.X",
        Int(-127, 127),
    ),
    (
        "perceptions[].channels[].actuator_resolution.Y",
        Int(-127, 127),
    ),
    (
        "perceptions[].channels[].actuator_resolution.Z",
        Int(-127, 127),
    ),
    (
        "perceptions[].channels[].actuator_target[]",
        Required(&["X", "Y", "Z"]),
    ),
    (
        "perceptions[].channels[].actuator_target[].X",
        Int(-127, 127),
    ),
    (
        "perceptions[].channels[].actuator_target[].Y",
        Int(-127, 127),
    ),
    (
        "perceptions[].channels[].actuator_target[].Z",
        Int(-127, 127),
    ),
    ("perceptions[].channels[].frequency_sampling", Int(0, ANY)),
    ("perceptions[].channels[].sample_count", Int(0, ANY)),
    ("perceptions[].channels[].bands", Array(0)),
    (
        "perceptions[].channels[].bands[]",
        Required(&[
            "band_type",
            "lower_frequency_limit",
            "upper_frequency_limit",
            "effects",
        ]),
    ),
    (
        "perceptions[].channels[].bands[].band_type",
        Enum(&["WaveletWave", "VectorialWave", "Curve", "Transient"]),
    ),
    ("perceptions[].channels[].bands[].priority", Int(0, ANY)),
    (
        "perceptions[].channels[].bands[].curve_type",
        Enum(&["Linear", "Cubic", "Akima", "Bezier", "BSpline", "Unknown"]),
    ),
    (
        "perceptions[].channels[].bands[].block_length",
        Int(16, ANY),
    ),
    (
        "perceptions[].channels[].bands[].lower_frequency_limit",
        Num(0.0, 10_000.0),
    ),
    (
        "perceptions[].channels[].bands[].upper_frequency_limit",
        Num(0.0, 10_000.0),
    ),
    ("perceptions[].channels[].bands[].effects", Array(0)),
    (
        "perceptions[].channels[].bands[].effects[]",
        Required(&["effect_type"]),
    ),
    ("perceptions[].channels[].bands[].effects[].id", Int(0, ANY)),
    (
        "perceptions[].channels[].bands[].effects[].effect_type",
        Enum(&["Basis", "Composite", "Reference"]),
    ),
    (
        "perceptions[].channels[].bands[].effects[].position",
        Int(0, ANY),
    ),
    (
        "perceptions[].channels[].bands[].effects[].phase",
        // The schema's own figure for 2 pi, five decimals.
        #[allow(clippy::approx_constant)]
        Num(0.0, 6.28318),
    ),
    (
        "perceptions[].channels[].bands[].effects[].base_signal",
        Enum(&["Sine", "Square", "Triangle", "SawToothUp", "SawToothDown"]),
    ),
    (
        "perceptions[].channels[].bands[].effects[].keyframes[].amplitude_modulation",
        Num(-1.0, 1.0),
    ),
    (
        "perceptions[].channels[].bands[].effects[].keyframes[].frequency_modulation",
        Num(0.0, 10_000.0),
    ),
    (
        "perceptions[].channels[].bands[].effects[].keyframes[].relative_position",
        Int(0, ANY),
    ),
];

/// Every value at `path` under `v` (`a.b[].c`); none when a member is absent.
fn at<'a>(v: &'a Value, path: &str) -> Vec<&'a Value> {
    let mut found = vec![v];
    for step in path.split('.').filter(|p| !p.is_empty()) {
        let (key, each) = match step.strip_suffix("[]") {
            Some(k) => (k, true),
            None => (step, false),
        };
        found = found
            .into_iter()
            .filter_map(|x| x.get(key))
            .flat_map(|x| match (each, x.as_array()) {
                (true, Some(items)) => items.iter().collect(),
                (true, None) => vec![],
                (false, _) => vec![x],
            })
            .collect();
    }
    found
}

/// The breaches of [`RULES`] and of the version's pattern in `doc`, in words.
fn breaches(doc: &Value) -> Vec<String> {
    let mut out = Vec::new();
    for &(path, rule) in RULES {
        for v in at(doc, path) {
            let ok = match rule {
                Int(lo, hi) => v.as_i64().is_some_and(|x| (lo..=hi).contains(&x)),
                Num(lo, hi) => v.as_f64().is_some_and(|x| (lo..=hi).contains(&x)),
                Enum(names) => v.as_str().is_some_and(|x| names.contains(&x)),
                Str => v.is_string(),
                Array(min) => v.as_array().is_some_and(|a| a.len() >= min),
                Required(keys) => keys.iter().all(|k| v.get(k).is_some()),
            };
            if !ok {
                out.push(format!("{path}: {v} breaks {rule:?}"));
            }
        }
    }
    // `^[0-9]{4}(-[0-9])?$`
    let version = doc["version"].as_str().unwrap_or_default();
    let (year, rest) = version.split_at(version.len().min(4));
    let digits = |t: &str| t.bytes().all(|b| b.is_ascii_digit());
    let rest_ok =
        rest.is_empty() || (rest.len() == 2 && rest.starts_with('-') && digits(&rest[1..]));
    if !(year.len() == 4 && digits(year) && rest_ok) {
        out.push(format!("version {version:?} breaks ^[0-9]{{4}}(-[0-9])?$"));
    }
    out
}

/// Exports `stimulus` to `.hjif` with `extra` flags and returns the document.
fn exported(stimulus: &std::path::Path, extra: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.hjif");
    let run = crate::bin::command()
        .args(["export", s(stimulus), "--to", "hjif", "-o", s(&out)])
        .args(extra)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", stderr(&run));
    serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap()
}

#[test]
fn every_exported_hjif_meets_mpegs_schema() {
    let mut files: Vec<_> = std::fs::read_dir("../examples/emoji")
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "touch"))
        .collect();
    files.sort();
    assert!(files.len() >= 6);
    let dir = tempfile::tempdir().unwrap();
    // Full scale both ways on every channel, and silence.
    let extreme = dir.path().join("extreme.touch");
    let swing: stimuli::Shape = |x| (7.0 * x).sin().signum();
    std::fs::write(
        &extreme,
        stimuli::stimulus("extreme", &stimuli::one_second(0.99, &[(3, swing)])),
    )
    .unwrap();
    let silent = dir.path().join("silent.touch");
    std::fs::write(
        &silent,
        stimuli::stimulus("silent", &stimuli::one_second(0.0, &[])),
    )
    .unwrap();
    files.extend([extreme, silent]);
    for f in &files {
        for extra in [&[][..], &["--resonance-hz", "150"]] {
            let doc = exported(f, extra);
            let bad = breaches(&doc);
            assert!(bad.is_empty(), "{} {extra:?}: {bad:#?}", f.display());
        }
    }
}

/// The checker itself finds what the schema forbids (else the test above proves nothing).
#[test]
fn the_schema_table_catches_a_breach_of_each_kind() {
    let doc = exported(std::path::Path::new("../examples/emoji/love.touch"), &[]);
    assert!(breaches(&doc).is_empty());
    let cases: [(&str, Value); 5] = [
        ("/perceptions/0/reference_devices/0/id", Value::from(0)),
        (
            "/perceptions/0/channels/0/bands/0/effects/0/keyframes/1/amplitude_modulation",
            Value::from(1.5),
        ),
        ("/perceptions/0/perception_modality", Value::from("Touch")),
        ("/version", Value::from("23")),
        ("/avatars/0/id", Value::from(0)),
    ];
    for (pointer, value) in cases {
        let mut bad = doc.clone();
        *bad.pointer_mut(pointer)
            .unwrap_or_else(|| panic!("{pointer}")) = value;
        assert!(!breaches(&bad).is_empty(), "{pointer} passed");
    }
    let mut missing = doc.clone();
    missing["perceptions"][0]["channels"][0]
        .as_object_mut()
        .unwrap()
        .remove("gain");
    assert!(!breaches(&missing).is_empty());
}
