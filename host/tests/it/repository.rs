//! The repository stands on its own: no file reads or names a path outside the clone or a
//! document that is not in it, the licences the crates declare are there, and the
//! documents that source comments cite exist.

use std::path::{Path, PathBuf};

/// The workspace root (the clone).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// Every text file of the clone, skipping build output, VCS data and data files.
fn text_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        let kind = entry.file_type().unwrap();
        if kind.is_dir() {
            if !matches!(name.as_str(), "target" | ".git" | "corpus" | "artifacts") {
                text_files(&path, out);
            }
        } else if kind.is_file() {
            if let Ok(text) = std::fs::read_to_string(&path) {
                if !text.contains('\0') {
                    out.push(path);
                }
            }
        }
    }
}

#[test]
fn nothing_names_a_path_outside_the_clone_or_a_missing_document() {
    let mut files = Vec::new();
    text_files(&root(), &mut files);
    assert!(files.len() > 50, "walked only {} files", files.len());
    // Spelled in pieces so that this file does not match itself.
    let forbidden = [
        ["../", "shared"].concat(),
        ["/work/", "shared"].concat(),
        ["ALGORITHM", ".md"].concat(),
        ["HARDWARE", ".md"].concat(),
        ["TOUCHC_REFERENCE", "_DIR"].concat(),
        ["example", ".invalid"].concat(),
    ];
    let mut hits = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for word in &forbidden {
            if text.contains(word.as_str()) {
                hits.push(format!("{}: {word}", file.display()));
            }
        }
    }
    assert!(hits.is_empty(), "{hits:#?}");
}

#[test]
fn cited_documents_and_declared_licences_exist() {
    let root = root();
    for doc in [
        "docs/algorithm.md",
        "docs/hardware.md",
        "protocol/SPEC.md",
        "tests/data/reference/README.md",
        "LICENSE-MIT",
        "LICENSE-APACHE",
    ] {
        assert!(root.join(doc).is_file(), "{doc} is missing");
    }
    let mit = std::fs::read_to_string(root.join("LICENSE-MIT")).unwrap();
    assert!(mit.contains("Copyright (c) the touchc contributors"));
    assert!(mit.contains("Permission is hereby granted, free of charge"));
    let apache = std::fs::read_to_string(root.join("LICENSE-APACHE")).unwrap();
    assert!(apache.contains("Apache License") && apache.contains("Version 2.0, January 2004"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    assert!(manifest.contains("license = \"MIT OR Apache-2.0\""));
    // Every `docs/*.md` a comment or document cites is in the clone.
    let mut files = Vec::new();
    text_files(&root, &mut files);
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for (at, _) in text.match_indices("docs/") {
            let cited: String = text[at..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '/' | '.' | '_' | '-'))
                .collect();
            let cited = cited.trim_end_matches('.');
            if cited.ends_with(".md") {
                assert!(
                    root.join(cited).is_file(),
                    "{} cites {cited}, which is not in the clone",
                    file.display()
                );
            }
        }
    }
}
