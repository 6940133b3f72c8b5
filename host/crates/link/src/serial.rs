//! Serial ports: a sleeve's USB socket (CDC-ACM) or its USART through a
//! USB-serial adapter.

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use super::Transport;

/// The baud rate of the sleeve's USART. A CDC-ACM port ignores it.
pub(crate) const BAUD: u32 = 460_800;

/// A serial port opened for the link (8N1, no flow control).
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
}

impl SerialTransport {
    /// Opens `path` at `BAUD`, for this process alone.
    ///
    /// A port another process holds fails with [`io::ErrorKind::ResourceBusy`], its
    /// message naming the holders where the system tells ([`holders`]); the holder's
    /// exclusive mode is left as it was. A path that does not exist fails with
    /// [`io::ErrorKind::NotFound`].
    pub fn open(path: &Path) -> io::Result<SerialTransport> {
        check_free(path)?;
        let name = path.to_string_lossy();
        let port = serialport::new(name.as_ref(), BAUD)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(io::Error::from)?;
        // Bytes left over from before (a previous session, line noise) are not ours.
        let _ = port.clear(serialport::ClearBuffer::Input);
        Ok(SerialTransport { port })
    }
}

impl Transport for SerialTransport {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port
            .set_timeout(timeout.max(Duration::from_millis(1)))
            .map_err(io::Error::from)?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            Err(e) => Err(e),
        }
    }
}

/// Fails if another process holds `path`. Looked at with a descriptor of our own
/// before the serial library opens it: that library sets the port's exclusive
/// mode (`TIOCEXCL`) before it finds the holder's lock taken, and clears it again
/// (`TIOCNXCL`) as it gives up, which would unlock the holder's port for anyone
/// (a process running as root opens a port in exclusive mode all the same).
fn check_free(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(path);
        let busy = match file {
            // Another process holds it in exclusive mode (and this one is not root).
            Err(e) if e.raw_os_error() == Some(libc::EBUSY) => true,
            Err(e) => return Err(e),
            // Another process holds its lock (the serial library's `flock`). Ours
            // goes with the descriptor, which closes here.
            Ok(f) => matches!(f.try_lock(), Err(std::fs::TryLockError::WouldBlock)),
        };
        if busy {
            let who = holders(path);
            let by = if who.is_empty() {
                String::new()
            } else {
                let names: Vec<String> = who
                    .iter()
                    .map(|(pid, name)| format!("{name} (pid {pid})"))
                    .collect();
                format!(" by {}", names.join(", "))
            };
            return Err(io::Error::new(
                io::ErrorKind::ResourceBusy,
                format!("in use{by}"),
            ));
        }
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

/// The other processes that have `path` open, as (pid, name), where the system
/// says (Linux: `/proc/PID/fd`, readable for one's own processes, or all as root).
pub fn holders(path: &Path) -> Vec<(u32, String)> {
    let Ok(target) = std::fs::canonicalize(path) else {
        return Vec::new();
    };
    let me = std::process::id();
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for p in procs.flatten() {
        let Some(pid) = p.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else {
            continue;
        };
        if pid == me {
            continue;
        }
        let Ok(fds) = std::fs::read_dir(p.path().join("fd")) else {
            continue;
        };
        if fds
            .flatten()
            .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|l| l == target))
        {
            let name = std::fs::read_to_string(p.path().join("comm"))
                .map(|n| n.trim().to_string())
                .unwrap_or_else(|_| "?".into());
            out.push((pid, name));
        }
    }
    out.sort();
    out
}

/// A serial port that may be a sleeve.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Candidate {
    /// The device path (`/dev/ttyACM0`).
    pub path: PathBuf,
    /// Its USB vendor and product id, when it is on USB.
    pub usb: Option<(u16, u16)>,
    /// The USB product string, when there is one.
    pub product: Option<String>,
    /// The USB serial number string, when there is one (a sleeve's is its chip's
    /// unique ID: two sleeves on one computer differ in it).
    pub serial: Option<String>,
    /// The port has the sleeve's own USB ids (its OTG FS socket), not an adapter's.
    pub is_sleeve: bool,
}

/// The serial ports a sleeve may be on: every USB serial port (the sleeve's own
/// socket, by its ids, and USB-serial adapters, which may carry its USART). Ports
/// that are not on USB (a PC's built-in UARTs) are left out. On Linux the list
/// comes from sysfs, without libudev.
pub fn candidates(sleeve_ids: (u16, u16)) -> io::Result<Vec<Candidate>> {
    let ports = serialport::available_ports().map_err(io::Error::from)?;
    let mut out: Vec<Candidate> = ports
        .into_iter()
        .filter_map(|p| match p.port_type {
            serialport::SerialPortType::UsbPort(usb) => Some(Candidate {
                path: PathBuf::from(p.port_name),
                usb: Some((usb.vid, usb.pid)),
                product: usb.product,
                serial: usb.serial_number,
                is_sleeve: (usb.vid, usb.pid) == sleeve_ids,
            }),
            _ => None,
        })
        .collect();
    // The sleeve's own sockets first, then by path.
    out.sort_by(|a, b| b.is_sleeve.cmp(&a.is_sleeve).then(a.path.cmp(&b.path)));
    Ok(out)
}
