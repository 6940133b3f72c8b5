//! Whether standard output was closed when `touchc` started (`touchc ... >&-`).
//!
//! Rust's runtime opens `/dev/null` on a closed standard stream before `main` (so that
//! a file opened later cannot become descriptor 1 by accident), after which every write
//! to standard output "succeeds" and the output is silently lost. The state is therefore
//! recorded by a constructor that runs before the runtime's start-up, while descriptor
//! 1 is still closed, and [`Output`](super::output::Output) refuses to write there.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by [`record`] when descriptor 1 was not open at start-up.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Whether standard output was closed when the process started.
pub fn stdout_was_closed() -> bool {
    STDOUT_CLOSED.load(Ordering::Relaxed)
}

/// The error a write to a closed standard output gets.
pub fn closed_error() -> std::io::Error {
    std::io::Error::other("it is closed (bad file descriptor)")
}

#[cfg(target_os = "linux")]
mod startup {
    use std::ffi::c_int;
    use std::sync::atomic::Ordering;

    /// `F_GETFD` on Linux, every architecture.
    const F_GETFD: c_int = 1;

    extern "C" {
        fn fcntl(fd: c_int, cmd: c_int, ...) -> c_int;
    }

    /// Runs from the ELF `.init_array`, before the Rust runtime starts (which is what
    /// would reopen descriptor 1 on `/dev/null`).
    extern "C" fn record() {
        // SAFETY: `fcntl(F_GETFD)` only reads the descriptor's flags; on a closed
        // descriptor it fails with EBADF and changes nothing.
        let flags = unsafe { fcntl(1, F_GETFD) };
        if flags == -1 {
            super::STDOUT_CLOSED.store(true, Ordering::Relaxed);
        }
    }

    #[used]
    #[link_section = ".init_array"]
    static RECORD: extern "C" fn() = record;
}
