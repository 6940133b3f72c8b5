//! Sizes a reader can hold: no source file over 600 lines outside its tests, no function
//! over 100 lines. Read from the workspace's Rust sources as text: a file's own
//! `#[cfg(test)] mod` and everything after it are its tests; files of tests, benches,
//! examples and fuzz targets are tests throughout. The twin's Python modules hold to the
//! same 600 lines a file.

use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 600;
const MAX_FN_LINES: usize = 100;

/// The folders whose Rust sources are the product, from the workspace's root.
const SOURCES: &[&str] = &["protocol/src", "host/src", "host/crates", "firmware"];

/// Path parts that mark tests, fixtures or build output.
const NOT_PRODUCT: &[&str] = &[
    "tests", "benches", "examples", "fuzz", "target", "testkit", "test-rng",
];

fn rust_sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            if !NOT_PRODUCT.contains(&name.as_str()) && !name.starts_with('.') {
                rust_sources(&path, out);
            }
        } else if name.ends_with(".rs") && name != "tests.rs" {
            out.push(path);
        }
    }
}

/// The lines before the file's test module.
fn product_lines(text: &str) -> Vec<&str> {
    let lines: Vec<&str> = text.lines().collect();
    let end = lines
        .windows(2)
        .position(|w| {
            let next = w[1].trim_start();
            w[0].trim() == "#[cfg(test)]"
                && (next.starts_with("mod ")
                    || next.starts_with("pub mod ")
                    || next.starts_with("pub(crate) mod "))
        })
        .unwrap_or(lines.len());
    lines[..end].to_vec()
}

/// The functions with a body, as (name, first line, lines from `fn` to its closing
/// brace); a body ends at the first `}` alone at the `fn`'s indentation.
fn functions(lines: &[&str]) -> Vec<(String, usize, usize)> {
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let mut words = trimmed.split_whitespace().peekable();
        while words.peek().is_some_and(|w| {
            w.starts_with("pub") || ["const", "async", "unsafe", "extern", "\"C\""].contains(w)
        }) {
            words.next();
        }
        if words.next() != Some("fn") || trimmed.trim_end().ends_with('}') {
            continue;
        }
        let Some(name) = words
            .next()
            .map(|w| w.split(['(', '<']).next().unwrap_or_default().to_string())
        else {
            continue;
        };
        // The signature ends at the line that opens the body or ends a declaration.
        let Some(open) = (i..lines.len()).find(|&j| {
            let l = lines[j].trim_end();
            l.ends_with('{') || l.ends_with(';')
        }) else {
            continue;
        };
        if !lines[open].trim_end().ends_with('{') {
            continue;
        }
        let close = format!("{indent}}}");
        if let Some(end) = (open + 1..lines.len()).find(|&k| lines[k].trim_end() == close) {
            found.push((name, i + 1, end - i + 1));
        }
    }
    found
}

#[test]
fn the_counter_sees_long_functions_and_skips_tests() {
    let mut text = String::from("pub(crate) fn long(\n    a: u8,\n) -> u8 {\n");
    text.push_str(&"    let _ = a;\n".repeat(98));
    text.push_str("    a\n}\n\nfn short() {}\n\n#[cfg(test)]\nmod tests {\n");
    text.push_str(&"    fn t() {\n        x();\n    }\n".repeat(300));
    text.push_str("}\n");
    let lines = product_lines(&text);
    assert_eq!(lines.len(), 106);
    assert_eq!(functions(&lines), vec![("long".to_string(), 1, 103)]);
}

#[test]
fn no_file_over_600_lines_and_no_function_over_100() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for dir in SOURCES {
        rust_sources(&root.join(dir), &mut files);
    }
    files.sort();
    assert!(files.len() > 100, "only {} sources found", files.len());
    let mut over = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).expect("a source file reads as UTF-8");
        let lines = product_lines(&text);
        let shown = path.strip_prefix(&root).unwrap_or(path).display();
        if lines.len() > MAX_FILE_LINES {
            over.push(format!("{shown}: {} lines", lines.len()));
        }
        for (name, at, length) in functions(&lines) {
            if length > MAX_FN_LINES {
                over.push(format!("{shown}:{at}: fn {name}, {length} lines"));
            }
        }
    }
    assert!(
        over.is_empty(),
        "split these by what they do (at most {MAX_FILE_LINES} lines a file, \
         {MAX_FN_LINES} a function):\n{}",
        over.join("\n")
    );
}

/// The twin's Python modules (not its tests, `test_*.py`) hold to the same rule per
/// file: the model of a board is read as much as the firmware it runs.
#[test]
fn no_twin_module_over_600_lines() {
    let twin = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/twin");
    let mut modules: Vec<PathBuf> = std::fs::read_dir(&twin)
        .expect("firmware/twin is there")
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            name.ends_with(".py") && !name.starts_with("test_")
        })
        .collect();
    modules.sort();
    assert!(
        modules.len() >= 8,
        "only {} twin modules found",
        modules.len()
    );
    let over: Vec<String> = modules
        .iter()
        .filter_map(|p| {
            let lines = std::fs::read_to_string(p).ok()?.lines().count();
            let name = p.file_name()?.to_string_lossy().into_owned();
            (lines > MAX_FILE_LINES).then(|| format!("firmware/twin/{name}: {lines} lines"))
        })
        .collect();
    assert!(
        over.is_empty(),
        "split these by what they do:\n{}",
        over.join("\n")
    );
}
