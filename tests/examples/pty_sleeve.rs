//! The in-memory sleeve on a pseudo-terminal, for tests that drive the real `touchc`
//! from outside Rust (scripts/study-browser.sh): prints the port's path, then serves
//! until its standard input closes.
//!
//! `cargo run -p touch-e2e --example pty_sleeve [SPEED]` (device ms per host ms, 10).

use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[path = "../tests/common/pty_sleeve.rs"]
mod pty_sleeve;

fn main() {
    let speed = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let stop = Arc::new(AtomicBool::new(false));
    println!("{}", pty_sleeve::serve(speed, stop.clone()));
    let _ = std::io::stdin().read_to_end(&mut Vec::new());
    stop.store(true, Ordering::Relaxed);
}
