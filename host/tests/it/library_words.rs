//! The libraries speak in values, the command line in words: no library crate names a
//! command-line flag in its text (an error's or a warning's), so that the flags can
//! change without the engine and the engine can serve another front end.

use std::path::{Path, PathBuf};

use touchc_input::recording::RecordingError;
use touchc_model::config::Knob;
use touchc_pipeline::compile::CompileError;
use touchc_rendering::condition::LimitViolation;
use touchc_tracking::track::TrackError;

/// The library crates' folder.
fn crates() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("crates")
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The string literals of Rust source `text`, outside comments, up to its first
/// `#[cfg(test)]` module (tests may name anything).
fn string_literals(text: &str) -> Vec<String> {
    let end = text.find("#[cfg(test)]\nmod").unwrap_or(text.len());
    let chars: Vec<char> = text[..end].chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        match chars[i] {
            '/' if chars.get(i + 1) == Some(&'/') => {
                while i < chars.len() && chars[i] != '\n' {
                    i += 1;
                }
            }
            '/' if chars.get(i + 1) == Some(&'*') => {
                while i + 1 < chars.len() && !(chars[i] == '*' && chars[i + 1] == '/') {
                    i += 1;
                }
                i += 2;
            }
            // A char literal (`'"'`, `'\''`); a lifetime has no closing quote.
            '\'' => {
                if chars.get(i + 1) == Some(&'\\') {
                    i += 4;
                } else if chars.get(i + 2) == Some(&'\'') {
                    i += 3;
                } else {
                    i += 1;
                }
            }
            '"' => {
                let mut literal = String::new();
                i += 1;
                while i < chars.len() && chars[i] != '"' {
                    if chars[i] == '\\' {
                        i += 1;
                    }
                    if let Some(&c) = chars.get(i) {
                        literal.push(c);
                    }
                    i += 1;
                }
                out.push(literal);
                i += 1;
            }
            _ => i += 1,
        }
    }
    out
}

/// `--` followed by a letter: a long flag.
fn names_a_flag(text: &str) -> bool {
    text.match_indices("--").any(|(at, _)| {
        text[at + 2..]
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_lowercase())
    })
}

#[test]
fn the_scanner_finds_a_flag_in_a_string_and_none_in_a_comment() {
    let text = "// use --fit\nlet c = '\"';\n#[error(\"breaks (use \\\n --fit)\")]\n\
                /* --rate */ let s = \"a-b -- c\";";
    let flagged: Vec<_> = string_literals(text)
        .into_iter()
        .filter(|s| names_a_flag(s))
        .collect();
    assert_eq!(flagged, vec!["breaks (use \n --fit)".to_string()]);
}

#[test]
fn no_library_crate_names_a_command_line_flag() {
    let mut files = Vec::new();
    let root = crates();
    sources(&root, &mut files);
    assert!(files.len() > 40, "read only {} files", files.len());
    let mut hits = Vec::new();
    for file in &files {
        // The test kit runs the binary: its flags are its business.
        if file
            .strip_prefix(&root)
            .is_ok_and(|p| p.starts_with("testkit"))
        {
            continue;
        }
        let text = std::fs::read_to_string(file).unwrap();
        for literal in string_literals(&text) {
            if names_a_flag(&literal) {
                hits.push(format!("{}: {literal:?}", file.display()));
            }
        }
    }
    assert!(hits.is_empty(), "{hits:#?}");
}

/// The errors whose advice names a flag say only what happened; the command line adds
/// the flag to try.
#[test]
fn errors_that_call_for_a_flag_leave_it_to_the_command_line() {
    let limits = CompileError::Limits(LimitViolation::Thermal {
        channel: 5,
        sample: 30_000,
        bucket_a2s: 30.5,
        budget_a2s: 30.0,
    });
    let dense = TrackError::TooDense {
        detections: 90_000,
        limit: 50_000_000,
    };
    for text in [limits.to_string(), dense.to_string()] {
        assert!(!names_a_flag(&text), "{text}");
    }
}

/// Errors whose remedy is a knob or another file state what happened; the command line
/// names the knobs and words the remedy.
#[test]
fn recording_errors_leave_knobs_and_remedies_to_the_command_line() {
    let too_large = RecordingError::MemberTooLarge {
        name: "big.npz".into(),
        entry: "pressure.npy".into(),
        needed: 1 << 40,
        budget: 1 << 29,
    };
    let too_short = RecordingError::TooShort {
        name: "short.npy".into(),
        frames: 30,
        tare: 20,
        min: 41,
    };
    for text in [too_large.to_string(), too_short.to_string()] {
        assert!(!names_a_flag(&text), "{text}");
        assert!(!text.contains("save the array"), "{text}");
        for knob in Knob::ALL {
            assert!(!text.contains(&knob.to_string()), "{text}");
        }
    }
}
