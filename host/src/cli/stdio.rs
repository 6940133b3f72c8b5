//! Whether standard output was closed when `touchc` started (`touchc ... >&-`).
//!
//! Rust's runtime opens `/dev/null` on a closed standard stream before `main` (so that
//! a file opened later cannot become descriptor 1 by accident), after which every write
//! to standard output "succeeds" and the output is silently lost. The state is therefore
//! recorded by a constructor that runs before the runtime's start-up, while descriptor
//! 1 is still closed, and [`Output`](super::output::Output) refuses to write there,
//! whether it is named `-` or by a path to the descriptor (`/dev/stdout`,
//! `/proc/self/fd/1`), which would otherwise reach that `/dev/null`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Symlinks followed before giving up (Linux's own limit is 40).
const MAX_LINKS: usize = 40;

/// Set by [`record`] when descriptor 1 was not open at start-up.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Whether standard output was closed when the process started.
pub fn stdout_was_closed() -> bool {
    STDOUT_CLOSED.load(Ordering::Relaxed)
}

/// Whether `path` names this process's descriptor 1, directly or through symlinks:
/// `/dev/stdout`, `/dev/fd/1`, `/proc/self/fd/1`, `/proc/thread-self/fd/1`,
/// `/proc/<own pid>/fd/1`. Decided from the names alone, since the descriptor's own
/// target is the runtime's `/dev/null` when standard output was closed, and an explicit
/// `-o /dev/null` is a wish to be respected.
pub fn names_stdout(path: &Path) -> bool {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        if is_descriptor_one(&p) {
            return true;
        }
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {}
            _ => return false,
        }
        let Ok(link) = std::fs::read_link(&p) else {
            return false;
        };
        p = match p.parent() {
            Some(dir) if link.is_relative() => dir.join(link),
            _ => link,
        };
    }
    false
}

/// Whether `p` is the entry `1` of this process's (or one of its threads') descriptor
/// folder, `/proc/<pid>/fd` or `/proc/<pid>/task/<tid>/fd` once its folder is
/// canonical (`/proc/self` and `/dev/fd` are symlinks to those).
fn is_descriptor_one(p: &Path) -> bool {
    if p.file_name().is_none_or(|name| name != "1") {
        return false;
    }
    let Some(Ok(dir)) = p.parent().map(std::fs::canonicalize) else {
        return false;
    };
    let own = PathBuf::from(format!("/proc/{}", std::process::id()));
    let of_a_thread = || {
        let task = dir.parent().and_then(Path::parent);
        task == Some(own.join("task").as_path())
    };
    dir.file_name().is_some_and(|n| n == "fd") && (dir == own.join("fd") || of_a_thread())
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
