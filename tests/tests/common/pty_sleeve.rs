//! The in-memory sleeve (`sleeve_firmware::link::sim`, with the emoji bank) behind a
//! pseudo-terminal, so that the real `touchc` opens it as a serial port. Shared by
//! tests/study.rs and examples/pty_sleeve.rs (the browser test's sleeve).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};
use sleeve_firmware::link::sim::Device;
use touch_protocol::bank;

const EMOJI: &[u8] = include_bytes!("../../../examples/emoji/emoji.bank");

/// Runs the sleeve on the master side of a new pty, `speed` device milliseconds per
/// host millisecond, until `stop`; returns the path of the pty's slave side.
pub fn serve(speed: usize, stop: Arc<AtomicBool>) -> String {
    let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal");
    let name = slave.name().expect("the pty has a name");
    // Closed here so that touchc can open it (serialport opens ports exclusively).
    drop(slave);
    master.set_timeout(Duration::from_millis(1)).unwrap();
    std::thread::spawn(move || {
        let mut region = vec![0xFF; bank::REGION_LEN];
        region[..EMOJI.len()].copy_from_slice(EMOJI);
        let mut dev = Device::boot(&region, EMOJI);
        let mut buf = [0u8; 4096];
        while !stop.load(Ordering::Relaxed) {
            // With nobody on the slave side a read fails: wait for the next run.
            if let Ok(n) = master.read(&mut buf) {
                dev.write(&buf[..n]);
            }
            dev.run(speed);
            let out = dev.read();
            if !out.is_empty() {
                let _ = master.write_all(&out);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    });
    name
}
