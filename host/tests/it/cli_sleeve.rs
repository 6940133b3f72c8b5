//! `touchc sleeve` without a sleeve: every subcommand says so in one line and exits
//! 1; argument mistakes exit 2 before any port is opened. (The link itself is tested
//! against the firmware's server in the end-to-end crate and on the twin.)

use std::process::Output;

use crate::bin::{command, stderr};

/// `touchc ARGS...` with a temporary directory of its own, where no twin serves: a twin
/// running on this machine, or the link a killed one left behind, must not answer for
/// a sleeve that is not there.
fn touchc(args: &[&str]) -> Output {
    let tmp = tempfile::tempdir().unwrap();
    command()
        .args(args)
        .env("TMPDIR", tmp.path())
        .output()
        .unwrap()
}

/// Every subcommand, with arguments that parse.
const SUBCOMMANDS: &[&[&str]] = &[
    &["list"],
    &["info"],
    &["upload", "../examples/emoji/emoji.bank"],
    &["abort"],
    &["play", "0"],
    &["stop"],
    &["stream", "../examples/emoji/love.touch"],
    &["status"],
    &["status", "--watch"],
    &["events"],
];

/// True when this machine has a USB serial port, which may be a sleeve.
fn serial_ports_attached() -> bool {
    std::fs::read_dir("/dev").is_ok_and(|d| {
        d.flatten().any(|e| {
            let n = e.file_name();
            let n = n.to_string_lossy();
            n.starts_with("ttyACM") || n.starts_with("ttyUSB")
        })
    })
}

fn one_line_exit_1(args: &[&str], want: &str) {
    let out = touchc(args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
    assert!(err.contains(want), "{args:?}: {err}");
    assert!(out.stdout.is_empty(), "{args:?}: nothing on stdout");
}

#[test]
fn with_no_sleeve_attached_every_subcommand_says_so_and_exits_1() {
    if serial_ports_attached() {
        eprintln!("skipped: a USB serial port is attached here");
        return;
    }
    for args in SUBCOMMANDS.iter().filter(|a| a[0] != "list") {
        let mut full = vec!["sleeve"];
        full.extend_from_slice(args);
        one_line_exit_1(&full, "no sleeve attached");
    }
    // An empty list is an answer: exit 0, nothing listed, a note on how to try the
    // twin (exit 1 before).
    let out = touchc(&["sleeve", "list"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(out.stdout.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("firmware/twin/run.sh serve"), "{err}");
}

#[test]
fn a_port_that_does_not_exist_is_named_and_exits_1() {
    for args in SUBCOMMANDS.iter().filter(|a| a[0] != "list") {
        let mut full = vec!["sleeve", "--port", "/dev/no-such-sleeve"];
        full.extend_from_slice(args);
        one_line_exit_1(&full, "/dev/no-such-sleeve: no sleeve attached there");
    }
}

#[test]
fn a_port_that_is_not_a_sleeve_times_out_in_one_line() {
    // /dev/null opens but is no terminal: the serial port layer refuses it.
    let out = touchc(&["sleeve", "--port", "/dev/null", "info"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).starts_with("touchc: error: /dev/null"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn argument_mistakes_exit_2_before_opening_a_port() {
    for args in [
        &["sleeve"][..],
        &["sleeve", "play"],
        &["sleeve", "play", "300"],
        &["sleeve", "play", "x"],
        &["sleeve", "upload"],
        &["sleeve", "stream"],
        &["sleeve", "status", "--interval", "0"],
        &["sleeve", "events", "--count", "-1"],
        &["sleeve", "frobnicate"],
        &["sleeve", "--port"],
    ] {
        let out = touchc(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    }
    // A bank image with --layout: caught before the port is opened.
    let out = touchc(&[
        "sleeve",
        "--port",
        "/dev/no-such-sleeve",
        "upload",
        "../examples/emoji/emoji.bank",
        "--layout",
        "x.toml",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[test]
fn bad_files_are_named_before_opening_a_port() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.touch");
    std::fs::write(&junk, b"not a stimulus").unwrap();
    let j = junk.to_str().unwrap();
    for args in [
        &["sleeve", "--port", "/dev/no-such-sleeve", "stream", j][..],
        &["sleeve", "--port", "/dev/no-such-sleeve", "upload", j],
    ] {
        let out = touchc(args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(j), "{err}");
        assert!(
            !err.contains("no-such-sleeve"),
            "the file is checked first: {err}"
        );
    }
}

#[test]
fn help_documents_every_subcommand() {
    let out = touchc(&["sleeve", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for sub in [
        "list", "info", "upload", "abort", "play", "stop", "stream", "status", "events",
    ] {
        assert!(
            help.lines().any(|l| l.trim_start().starts_with(sub)),
            "{sub} missing from:\n{help}"
        );
        let out = touchc(&["sleeve", sub, "--help"]);
        assert!(out.status.success(), "{sub} --help");
    }
}

#[test]
fn the_link_a_killed_twin_left_behind_is_no_sleeve() {
    // A twin killed with SIGKILL leaves its link to a terminal; by the next session the
    // terminal can be another program's. Only a live twin's link counts.
    if serial_ports_attached() {
        eprintln!("skipped: a USB serial port is attached here");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    // /dev/null stands for the terminal: a character device, as a pseudo-terminal is.
    std::os::unix::fs::symlink("/dev/null", tmp.path().join("touchc-sleeve-twin")).unwrap();
    let run = |pid: Option<&str>| {
        if let Some(pid) = pid {
            std::fs::write(tmp.path().join("touchc-sleeve-twin.pid"), pid).unwrap();
        }
        command()
            .args(["sleeve", "info"])
            .env("TMPDIR", tmp.path())
            .output()
            .unwrap()
    };
    // No process named beside the link, then one that has ended.
    for pid in [None, Some("2147483646\n")] {
        let out = run(pid);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{pid:?}: {err}");
        assert!(err.contains("no sleeve attached"), "{pid:?}: {err}");
    }
    // A live process beside it: the link is taken for the twin (and /dev/null fails
    // as a port, which says the link was tried).
    let out = run(Some(&format!("{}\n", std::process::id())));
    assert!(
        stderr(&out).contains("/dev/null") || stderr(&out).contains("touchc-sleeve-twin"),
        "{}",
        stderr(&out)
    );
}
