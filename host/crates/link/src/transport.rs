//! Byte streams the link runs over: a trait, and an in-memory pair for tests.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// A bidirectional byte stream to a sleeve (a serial port, USB CDC-ACM, an
/// in-memory pipe, a simulated device). Frames and their meaning are the
/// [`Client`](super::Client)'s business; a transport only moves bytes.
pub trait Transport {
    /// Sends all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads what has arrived into `buf`, waiting at most `timeout` for the first
    /// byte. `Ok(0)` means nothing came in time; a stream that can never deliver
    /// again (the other end is gone) is an error.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// The time on the clock that [`Transport::read`]'s timeouts count: the host's
    /// monotonic clock, unless the other end is a simulated device with its own.
    fn now(&self) -> Duration {
        host_clock()
    }
}

/// Time since the first call, on the host's monotonic clock.
fn host_clock() -> Duration {
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed()
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        (**self).read(buf, timeout)
    }

    fn now(&self) -> Duration {
        (**self).now()
    }
}

/// One direction of a [`MemoryTransport`] pair.
#[derive(Default)]
struct Pipe {
    state: Mutex<PipeState>,
    ready: Condvar,
}

#[derive(Default)]
struct PipeState {
    bytes: VecDeque<u8>,
    closed: bool,
}

impl Pipe {
    fn lock(&self) -> std::sync::MutexGuard<'_, PipeState> {
        // A panic elsewhere while holding the lock leaves plain bytes behind: still usable.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// One end of an in-memory byte stream: what one end writes, the other reads.
/// Dropping an end closes the stream: the other end's reads fail once it has
/// read what was sent before, and its writes fail at once.
pub struct MemoryTransport {
    rx: Arc<Pipe>,
    tx: Arc<Pipe>,
}

impl MemoryTransport {
    /// Two connected ends (host, device).
    pub fn pair() -> (MemoryTransport, MemoryTransport) {
        let a = Arc::new(Pipe::default());
        let b = Arc::new(Pipe::default());
        (
            MemoryTransport {
                rx: a.clone(),
                tx: b.clone(),
            },
            MemoryTransport { rx: b, tx: a },
        )
    }

    /// Takes every byte that has arrived, without waiting.
    pub fn drain(&mut self) -> Vec<u8> {
        self.rx.lock().bytes.drain(..).collect()
    }
}

impl Drop for MemoryTransport {
    fn drop(&mut self) {
        for pipe in [&self.rx, &self.tx] {
            pipe.lock().closed = true;
            pipe.ready.notify_all();
        }
    }
}

impl Transport for MemoryTransport {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let mut state = self.tx.lock();
        if state.closed {
            return Err(io::ErrorKind::BrokenPipe.into());
        }
        state.bytes.extend(bytes);
        self.tx.ready.notify_all();
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = Instant::now() + timeout;
        let mut state = self.rx.lock();
        loop {
            if !state.bytes.is_empty() {
                let n = buf.len().min(state.bytes.len());
                for (slot, byte) in buf.iter_mut().zip(state.bytes.drain(..n)) {
                    *slot = byte;
                }
                return Ok(n);
            }
            if state.closed {
                return Err(io::ErrorKind::UnexpectedEof.into());
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(0);
            }
            state = self
                .rx
                .ready
                .wait_timeout(state, deadline - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_cross_in_order_and_a_dropped_end_closes_the_stream() {
        let (mut host, mut device) = MemoryTransport::pair();
        host.write_all(b"abc").unwrap();
        host.write_all(b"d").unwrap();
        let mut buf = [0; 8];
        assert_eq!(device.read(&mut buf, Duration::ZERO).unwrap(), 4);
        assert_eq!(&buf[..4], b"abcd");
        assert_eq!(device.read(&mut buf, Duration::from_millis(5)).unwrap(), 0);
        device.write_all(b"z").unwrap();
        drop(device);
        assert_eq!(
            host.read(&mut buf, Duration::ZERO).unwrap(),
            1,
            "sent before the drop"
        );
        assert!(host.read(&mut buf, Duration::ZERO).is_err());
        assert!(host.write_all(b"x").is_err());
    }

    #[test]
    fn a_read_waits_for_a_write_from_another_thread() {
        let (mut host, mut device) = MemoryTransport::pair();
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            device.write_all(b"late").unwrap();
            device
        });
        let mut buf = [0; 8];
        assert_eq!(host.read(&mut buf, Duration::from_secs(5)).unwrap(), 4);
        drop(t.join().unwrap());
    }
}
