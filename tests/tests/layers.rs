//! The host's layers hold: each crate under `host/crates/` depends only on crates of a
//! lower layer, so no crate imports upward and there is no circle. Read from `cargo
//! metadata`, the graph Cargo itself builds; `cargo test -p touch-e2e --test layers --
//! --nocapture` prints it.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

/// Every crate of the host in its layer, lowest first. A crate may depend on crates of
/// lower layers only; a new crate must be placed here.
const LAYERS: &[(&str, u32)] = &[
    // Helpers that know nothing of touch.
    ("touchc-wide", 0),
    ("touchc-test-rng", 0),
    ("touchc-link", 0),
    // Perception studies and their statistics.
    ("touchc-study", 0),
    // The model every stage shares.
    ("touchc-model", 1),
    // The stages, in pipeline order, and what reads a finished stimulus.
    ("touchc-input", 2),
    // Synthetic recordings with their truth: for tests, evaluation and `touchc synth`,
    // never for the pipeline's stages.
    ("touchc-synth", 2),
    ("touchc-export", 2),
    // The fixtures of the tests, benches and examples: recordings from the
    // synthesiser, reference trajectories as the model's type. Below the stages, so
    // each stage's own tests can use them.
    ("touchc-testkit", 3),
    ("touchc-tracking", 4),
    // Instance selection: recordings scored per class by cross-validated classifiers
    // (its synthetic data sets from the synthesiser).
    ("touchc-select", 4),
    ("touchc-placement", 5),
    ("touchc-rendering", 6),
    ("touchc-encoding", 7),
    // The one driver of the stages, then what measures it.
    ("touchc-pipeline", 8),
    ("touchc-eval", 9),
    // The command line and its pictures.
    ("touchc", 10),
];

fn workspace_graph() -> BTreeMap<String, Vec<(String, String)>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(&root)
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    let mut graph = BTreeMap::new();
    for package in meta["packages"].as_array().expect("packages") {
        let name = package["name"].as_str().expect("name").to_string();
        let deps = package["dependencies"]
            .as_array()
            .expect("dependencies")
            .iter()
            .map(|d| {
                let kind = d["kind"].as_str().unwrap_or("normal").to_string();
                (
                    d["name"].as_str().expect("dependency name").to_string(),
                    kind,
                )
            })
            .collect();
        graph.insert(name, deps);
    }
    graph
}

#[test]
fn no_crate_of_the_host_depends_on_its_own_or_a_higher_layer() {
    let layer: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let graph = workspace_graph();
    let mut upward = Vec::new();
    for (name, deps) in &graph {
        if name.starts_with("touchc") && !name.starts_with("touchc-fuzz") {
            assert!(
                layer.contains_key(name.as_str()),
                "{name} is in no layer: place it in LAYERS"
            );
        }
        let Some(&own) = layer.get(name.as_str()) else {
            continue;
        };
        let mut shown = Vec::new();
        for (dep, kind) in deps {
            let Some(&theirs) = layer.get(dep.as_str()) else {
                continue;
            };
            shown.push(if kind == "normal" {
                dep.clone()
            } else {
                format!("{dep} ({kind})")
            });
            // Dev-dependencies too: a crate's tests import no higher layer either.
            if theirs >= own {
                upward.push(format!(
                    "{name} (layer {own}) -> {dep} (layer {theirs}, {kind})"
                ));
            }
        }
        println!("{name} (layer {own}) -> {}", shown.join(", "));
    }
    assert!(
        upward.is_empty(),
        "upward or sideways edges:\n{}",
        upward.join("\n")
    );
}

#[test]
fn the_model_imports_no_stage() {
    let graph = workspace_graph();
    let model = &graph["touchc-model"];
    let stages: Vec<_> = model
        .iter()
        .filter(|(dep, _)| dep.starts_with("touchc-"))
        .collect();
    assert!(stages.is_empty(), "touchc-model depends on {stages:?}");
}

#[test]
fn no_stage_of_the_pipeline_builds_the_synthesiser() {
    // The stages and their driver compile real recordings only; synthetic ones are for
    // tests (dev-dependencies), evaluation and `touchc synth`.
    let graph = workspace_graph();
    let stages = [
        "touchc-input",
        "touchc-tracking",
        "touchc-placement",
        "touchc-rendering",
        "touchc-encoding",
        "touchc-pipeline",
    ];
    let building: Vec<_> = stages
        .iter()
        .filter(|stage| {
            graph[**stage]
                .iter()
                .any(|(dep, kind)| dep == "touchc-synth" && kind == "normal")
        })
        .collect();
    assert!(
        building.is_empty(),
        "these stages depend on touchc-synth: {building:?}"
    );
}
