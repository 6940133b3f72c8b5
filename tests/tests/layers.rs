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

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path, found: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() && !path.ends_with("target") {
            rust_files(&path, found);
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            found.push(path);
        }
    }
}

#[test]
fn every_layer_is_imported_by_its_own_crate_name() {
    // The `touchc` library is the command line's pictures and sound and its process
    // setup (`viz`, `memory`), not a second name for the layers: an item reached as
    // `touchc::config` and as `touchc_model::config`
    // is one fact with two names, and the old one outlives every move.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let lib = std::fs::read_to_string(root.join("host/src/lib.rs")).unwrap();
    let reexports: Vec<_> = lib
        .lines()
        .filter(|line| line.trim_start().starts_with("pub use"))
        .collect();
    assert!(
        reexports.is_empty(),
        "host/src/lib.rs re-exports {reexports:?}"
    );

    let mut files = Vec::new();
    for dir in [
        "host/src",
        "host/tests",
        "host/benches",
        "host/examples",
        "host/fuzz",
        "tests",
    ] {
        rust_files(&root.join(dir), &mut files);
    }
    let mut through_touchc = Vec::new();
    // This file names the old paths to look for them.
    files.retain(|file| !file.ends_with("tests/tests/layers.rs"));
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        for (number, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(at) = rest.find("touchc::") {
                let after = &rest[at + "touchc::".len()..];
                let boundary = at == 0
                    || !rest.as_bytes()[at - 1].is_ascii_alphanumeric()
                        && rest.as_bytes()[at - 1] != b'_';
                let own = after.starts_with("viz") || after.starts_with("memory");
                if boundary && !own {
                    through_touchc.push(format!("{}:{}", file.display(), number + 1));
                }
                rest = after;
            }
        }
    }
    assert!(
        through_touchc.is_empty(),
        "these lines reach a layer through `touchc::`: {through_touchc:?}"
    );
}

#[test]
fn no_module_imports_a_sibling_or_its_parent_by_glob() {
    // `use super::*` hides which items a module needs and makes every split a
    // dependency of everything beside it; a test module (`mod tests`, `tests.rs`) may.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for dir in ["host/src", "host/crates", "protocol/src", "firmware/src"] {
        rust_files(&root.join(dir), &mut files);
    }
    let mut globs = Vec::new();
    for file in files {
        if file.ends_with("tests.rs") || file.components().any(|c| c.as_os_str() == "tests") {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        for (number, line) in text.lines().enumerate() {
            // Module level only: an indented glob sits in an inline `mod tests`.
            let glob = line.starts_with("use ") || line.starts_with("pub use ");
            if glob && line.ends_with("::*;") && !line.contains("prelude::*") {
                globs.push(format!("{}:{}: {line}", file.display(), number + 1));
            }
        }
    }
    assert!(globs.is_empty(), "glob imports: {globs:#?}");
}

/// The identifiers that follow each occurrence of `prefix` in `text`.
fn names_after<'a>(text: &'a str, prefix: &str) -> Vec<&'a str> {
    let mut names = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find(prefix) {
        let after = &rest[at + prefix.len()..];
        let end = after
            .find(|c: char| !c.is_ascii_alphanumeric() && c != '_')
            .unwrap_or(after.len());
        let before_ok = at == 0 || {
            let b = rest.as_bytes()[at - 1];
            !b.is_ascii_alphanumeric() && b != b'_' && b != b':'
        };
        if before_ok && end > 0 {
            names.push(&after[..end]);
        }
        rest = after;
    }
    names
}

#[test]
fn no_subcommand_reaches_back_into_the_router() {
    // `cli/mod.rs` routes; what subcommands share (reporting, reading inputs, writing
    // outputs) lives in modules beside them, so none depends on the router.
    let cli = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host/src/cli");
    let router = std::fs::read_to_string(cli.join("mod.rs")).unwrap();
    let modules: Vec<&str> = router
        .lines()
        .filter_map(|l| l.strip_prefix("mod ").and_then(|m| m.strip_suffix(';')))
        .collect();
    let mut files = Vec::new();
    rust_files(&cli, &mut files);
    let mut back = Vec::new();
    for file in files.iter().filter(|f| !f.ends_with("cli/mod.rs")) {
        let whole = std::fs::read_to_string(file).unwrap();
        // Up to the first inline module (`mod tests {`), whose `super` is this file.
        let text = whole
            .find("\nmod ")
            .filter(|&at| {
                whole[at + 1..]
                    .lines()
                    .next()
                    .is_some_and(|l| l.ends_with('{'))
            })
            .map_or(whole.as_str(), |at| &whole[..at]);
        // `super` from a file directly in cli/ is the router; from cli/sleeve/ it is
        // `super::super`.
        let nested = file.parent() != Some(cli.as_path());
        let mut names = names_after(text, "crate::cli::");
        if nested {
            names.extend(names_after(text, "super::super::"));
        } else if !file.ends_with("mod.rs") {
            names.extend(names_after(text, "super::"));
        }
        for name in names {
            if name != "super" && !modules.contains(&name) {
                back.push(format!("{}: {name}", file.display()));
            }
        }
    }
    assert!(
        back.is_empty(),
        "items of cli/mod.rs used by subcommands: {back:#?}"
    );
}

#[test]
fn the_architecture_doc_draws_the_graph_cargo_builds() {
    // docs/architecture.md's block: `touchc-x  what it does  -> a, b` (or `-> nothing`),
    // each crate's normal dependencies among the host's crates, without the prefix.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let doc = std::fs::read_to_string(root.join("docs/architecture.md")).unwrap();
    let block = doc
        .split("```text\n")
        .nth(1)
        .and_then(|rest| rest.split("```").next())
        .expect("docs/architecture.md has a ```text block");
    let graph = workspace_graph();
    let mut drawn = Vec::new();
    for line in block.lines() {
        let name = line.split_whitespace().next().unwrap_or_default();
        let (_, deps) = line
            .rsplit_once("-> ")
            .expect("every line names its dependencies");
        let mut deps: Vec<String> = if deps.starts_with("nothing") {
            Vec::new()
        } else {
            deps.split(", ").map(str::to_string).collect()
        };
        deps.sort();
        let mut built: Vec<String> = graph[name]
            .iter()
            .filter(|(dep, kind)| kind == "normal" && dep.starts_with("touchc-"))
            .map(|(dep, _)| dep.trim_start_matches("touchc-").to_string())
            .collect();
        built.sort();
        assert_eq!(
            deps, built,
            "docs/architecture.md draws {name}'s dependencies wrong"
        );
        drawn.push(name.to_string());
    }
    for (name, _) in LAYERS {
        assert!(
            drawn.iter().any(|d| d == name),
            "docs/architecture.md leaves out {name}"
        );
    }
}

#[test]
fn the_architecture_doc_names_every_source_file() {
    // A row per crate, `| `touchc-x` (`dir/`) | `a.rs`, `b/c.rs` | ...`: every file
    // under the crate's src/ (for `touchc`, host/src/) is named, and no file that is gone.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let doc = std::fs::read_to_string(root.join("docs/architecture.md")).unwrap();
    let mut checked = Vec::new();
    for row in doc.lines().filter(|l| l.starts_with("| `touchc")) {
        let cells: Vec<&str> = row.split(" | ").collect();
        let name = cells[0]
            .trim_start_matches("| `")
            .split('`')
            .next()
            .unwrap();
        let src = if name == "touchc" {
            root.join("host/src")
        } else {
            let dir = cells[0]
                .split("(`")
                .nth(1)
                .and_then(|d| d.split('/').next());
            root.join("host/crates")
                .join(dir.expect("the row names its folder"))
                .join("src")
        };
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let mut on_disk: Vec<String> = files
            .iter()
            .map(|f| {
                f.strip_prefix(&src)
                    .unwrap()
                    .to_string_lossy()
                    .replace('\\', "/")
            })
            .collect();
        on_disk.sort();
        let mut named: Vec<String> = cells[1]
            .split(", ")
            .map(|f| f.trim_matches('`').to_string())
            .collect();
        named.sort();
        assert_eq!(named, on_disk, "docs/architecture.md's row for {name}");
        checked.push(name.to_string());
    }
    for (name, _) in LAYERS {
        assert!(
            checked.iter().any(|c| c == name),
            "docs/architecture.md has no row for {name}"
        );
    }
}
