//! Writing results the way Unix tools do: whole files or nothing, `-` for standard
//! output, and devices, pipes and symlinked outputs written through to their target.
//!
//! A regular file is written to a temporary file beside it, flushed to disk and renamed
//! over it, so a failed or killed run never leaves a half-written output. The temporary
//! file is created with mode 0666 filtered by the umask (as any new file), or with the
//! mode of the file it replaces. While it is being written it holds an exclusive lock;
//! a run that is killed (SIGKILL skips every destructor) leaves its temporary file
//! unlocked, and the next run that writes into the same directory removes such leftovers
//! of its own name pattern that are older than itself.

#[cfg(unix)]
use std::fs::Permissions;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, SystemTime};

use tempfile::NamedTempFile;

/// Temporary files are `.touchc-XXXXXX.tmp`: hidden, and recognisably ours.
const TMP_PREFIX: &str = ".touchc-";
/// See [`TMP_PREFIX`].
const TMP_SUFFIX: &str = ".tmp";

/// Symlinks followed before giving up (Linux's own limit is 40).
const MAX_LINKS: usize = 40;

/// A file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {source}", shown(path))]
pub struct WriteError {
    /// The file that was being written (`-` is standard output).
    pub path: PathBuf,
    /// What went wrong.
    pub source: io::Error,
}

impl WriteError {
    /// Whether the reader went away (`touchc render --csv | head`): not a failure of
    /// the writer, so the CLI ends quietly.
    pub fn is_broken_pipe(&self) -> bool {
        self.source.kind() == io::ErrorKind::BrokenPipe
    }
}

/// How an output path is named in messages: `-` is standard output.
pub fn shown(path: &Path) -> String {
    if is_stdio(path) {
        "standard output".into()
    } else {
        path.display().to_string()
    }
}

/// Whether `path` is `-`, the conventional name of standard input or output.
pub fn is_stdio(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// An output being written; nothing is visible at its path until [`Output::finish`].
/// Dropped unfinished, a regular file's temporary is removed and the target untouched.
#[derive(Debug)]
pub struct Output {
    path: PathBuf,
    sink: Sink,
}

#[derive(Debug)]
enum Sink {
    /// `-`.
    Stdout(BufWriter<io::Stdout>),
    /// A device, a FIFO, a socket: written in place, since it cannot be replaced.
    Direct(BufWriter<File>),
    /// A regular file (new or existing): a temporary beside it, renamed over it.
    Atomic {
        tmp: BufWriter<NamedTempFile>,
        target: PathBuf,
    },
}

impl Output {
    /// Opens `path` for writing: `-` is standard output; an existing device or pipe
    /// (also through symlinks, such as `/dev/stdout`) is written in place; anything
    /// else goes to a temporary file beside the symlinks' final target.
    pub fn create(path: &Path) -> Result<Output, WriteError> {
        let fail = |source| WriteError {
            path: path.to_path_buf(),
            source,
        };
        if is_stdio(path) {
            return Ok(Self::stdout());
        }
        if super::stdio::stdout_was_closed() && super::stdio::names_stdout(path) {
            return Err(fail(super::stdio::closed_error()));
        }
        let target = resolve_links(path).map_err(fail)?;
        let existing = match std::fs::metadata(&target) {
            Ok(m) => Some(m),
            Err(e) if e.kind() == io::ErrorKind::NotFound => None,
            Err(e) => return Err(fail(e)),
        };
        if let Some(m) = &existing {
            if m.is_dir() {
                return Err(fail(io::Error::new(
                    io::ErrorKind::IsADirectory,
                    "is a directory",
                )));
            }
            if !m.is_file() {
                let file = OpenOptions::new()
                    .write(true)
                    .truncate(true)
                    .open(&target)
                    .map_err(fail)?;
                return Ok(Output {
                    path: path.to_path_buf(),
                    sink: Sink::Direct(BufWriter::new(file)),
                });
            }
        }
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        remove_stale_temporaries(dir, run_start());
        let mut builder = tempfile::Builder::new();
        builder.prefix(TMP_PREFIX).suffix(TMP_SUFFIX);
        #[cfg(unix)]
        builder.permissions(new_file_permissions());
        let tmp = builder
            .tempfile_in(dir)
            .map_err(|e| fail(without_path(e)))?;
        // Held until the descriptor closes: a live run's temporary is never removed.
        tmp.as_file()
            .try_lock()
            .map_err(|e| fail(io::Error::other(e.to_string())))?;
        if let Some(m) = existing {
            tmp.as_file()
                .set_permissions(m.permissions())
                .map_err(fail)?;
        }
        Ok(Output {
            path: path.to_path_buf(),
            sink: Sink::Atomic {
                tmp: BufWriter::new(tmp),
                target,
            },
        })
    }

    /// Standard output, buffered.
    pub fn stdout() -> Output {
        Output {
            path: PathBuf::from("-"),
            sink: Sink::Stdout(BufWriter::new(io::stdout())),
        }
    }

    /// Wraps an I/O error with this output's name (and without the temporary file's:
    /// tempfile names it in every error of its writer, a full disk's included).
    pub fn error(&self, source: io::Error) -> WriteError {
        WriteError {
            path: self.path.clone(),
            source: without_path(source),
        }
    }

    /// Flushes everything and, for a regular file, syncs it and renames it into place.
    pub fn finish(self) -> Result<(), WriteError> {
        let path = self.path;
        let fail = |source| WriteError {
            path: path.clone(),
            source,
        };
        match self.sink {
            Sink::Stdout(_) if super::stdio::stdout_was_closed() => {
                Err(fail(super::stdio::closed_error()))
            }
            Sink::Stdout(mut w) => w.flush().map_err(fail),
            Sink::Direct(mut w) => w.flush().map_err(fail),
            Sink::Atomic { tmp, target } => {
                let tmp = tmp
                    .into_inner()
                    .map_err(|e| fail(without_path(e.into_error())))?;
                tmp.as_file()
                    .sync_all()
                    .map_err(|e| fail(without_path(e)))?;
                tmp.persist(&target)
                    .map_err(|e| fail(without_path(e.error)))?;
                Ok(())
            }
        }
    }

    fn writer(&mut self) -> &mut dyn Write {
        match &mut self.sink {
            Sink::Stdout(_) if super::stdio::stdout_was_closed() => Box::leak(Box::new(Closed)),
            Sink::Stdout(w) => w,
            Sink::Direct(w) => w,
            Sink::Atomic { tmp, .. } => tmp,
        }
    }
}

/// Errors carry the output's name (as a [`WriteError`] inside the `io::Error`, whose
/// kind is kept, so a broken pipe is still recognisable).
impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer().write(buf).map_err(|e| self.wrap(e))
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.writer().write_all(buf).map_err(|e| self.wrap(e))
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer().flush().map_err(|e| self.wrap(e))
    }
}

impl Output {
    fn wrap(&self, e: io::Error) -> io::Error {
        if e.get_ref().is_some_and(|inner| inner.is::<WriteError>()) {
            return e;
        }
        io::Error::new(e.kind(), self.error(e))
    }
}

/// Standard output closed at start-up: every write fails (see [`super::stdio`]).
struct Closed;

impl Write for Closed {
    fn write(&mut self, _: &[u8]) -> io::Result<usize> {
        Err(super::stdio::closed_error())
    }

    fn flush(&mut self) -> io::Result<()> {
        Err(super::stdio::closed_error())
    }
}

/// Writes `bytes` to `path` as one [`Output`]: atomically for a regular file, in
/// place for a device or pipe, to standard output for `-`. On any error a regular
/// file is untouched and no temporary file is left behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let mut out = Output::create(path)?;
    out.writer().write_all(bytes).map_err(|e| out.error(e))?;
    out.finish()
}

/// The OS error alone: tempfile appends ` at path "<the temporary>"`, a name that
/// means nothing to the user (the message names the output instead).
fn without_path(e: io::Error) -> io::Error {
    let text = e.to_string();
    match text.find(" at path ") {
        Some(at) => io::Error::new(e.kind(), &text[..at]),
        None => e,
    }
}

/// Finds the file a chain of symlinks ends at, so that writing replaces the target,
/// not the link. A dangling link's target is created.
fn resolve_links(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {}
            _ => return Ok(p),
        }
        // /dev/stdout and /proc/self/fd/N name descriptors: their "targets" (pipe:[N])
        // are not paths. Opening the link itself reaches the descriptor's file.
        if p.starts_with("/proc") || p.starts_with("/dev") {
            return match std::fs::metadata(&p) {
                Ok(m) if m.is_file() => std::fs::canonicalize(&p),
                _ => Ok(p),
            };
        }
        let link = std::fs::read_link(&p)?;
        p = match p.parent() {
            Some(dir) if link.is_relative() => dir.join(link),
            _ => link,
        };
    }
    Err(io::Error::other(format!(
        "more than {MAX_LINKS} symlinks in a chain"
    )))
}

/// A file a command reads or writes, as the command line named it: `label` says which
/// argument it came from (`the recording`, `-o`, `--report`), for the refusal's message.
#[derive(Debug, Clone, Copy)]
pub struct Named<'a> {
    /// The argument, as a person reads it.
    pub label: &'a str,
    /// The path given (`-` is standard input or output).
    pub path: &'a Path,
}

/// `label` names `path`.
pub fn named<'a>(label: &'a str, path: &'a Path) -> Named<'a> {
    Named { label, path }
}

/// Refuses, before any work, a command whose outputs would write over one of its
/// inputs (the same path, or the same file through a symlink or a hard link) or over
/// each other: replacing an input loses it, and two outputs in one file lose one of
/// them. Devices, FIFOs and sockets are streams, not files a write replaces, so they
/// never clash; `-` outputs (standard output) clash with each other. The error is a
/// usage error (exit status 2) naming both files.
pub fn refuse_overwrites(inputs: &[Named<'_>], outputs: &[Named<'_>]) -> anyhow::Result<()> {
    use std::collections::HashMap;
    // By identity, so that a batch of thousands is checked in linear time; the first
    // input of an identity is the one named.
    let mut by_id: HashMap<Identity, Named<'_>> = HashMap::new();
    for n in inputs {
        if let Some(id) = Identity::of_input(n.path) {
            by_id.entry(id).or_insert(*n);
        }
    }
    let mut written: HashMap<Identity, Named<'_>> = HashMap::new();
    for out in outputs {
        let Some(out_id) = Identity::of_output(out.path) else {
            continue;
        };
        if let Some(input) = by_id.get(&out_id) {
            return Err(super::report::usage(format!(
                "{} {} is the same file as {} {}: writing it would destroy that input; \
                 choose another output",
                out.label,
                shown(out.path),
                input.label,
                super::input::input_name(input.path),
            )));
        }
        if let Some(other) = written.get(&out_id) {
            return Err(super::report::usage(format!(
                "{} {} and {} {} are the same file: one output would overwrite the other",
                other.label,
                shown(other.path),
                out.label,
                shown(out.path),
            )));
        }
        written.insert(out_id, *out);
    }
    Ok(())
}

/// What makes two paths one file, for [`refuse_overwrites`].
#[derive(Debug, PartialEq, Eq, Hash)]
enum Identity {
    /// Standard output.
    Stdout,
    /// An existing regular file: its device and inode on Unix, so that symlinks and
    /// hard links are seen through; its canonical path elsewhere.
    #[cfg(unix)]
    File { dev: u64, ino: u64 },
    /// A file by its absolute, normalised path: one that does not exist yet (an
    /// output), or any existing file where inodes are not available.
    Path(PathBuf),
}

impl Identity {
    /// An input's identity; `None` for what cannot be written over: a stream, a
    /// device, standard input that is not a regular file, a path that does not exist.
    fn of_input(path: &Path) -> Option<Identity> {
        if is_stdio(path) {
            return Self::of_stdin();
        }
        let meta = std::fs::metadata(path).ok()?;
        meta.is_file().then(|| Self::of_file(path, &meta))?
    }

    /// An output's identity; `None` for a device, FIFO or socket (written in place).
    fn of_output(path: &Path) -> Option<Identity> {
        if is_stdio(path) {
            return Some(Identity::Stdout);
        }
        match std::fs::metadata(path) {
            Ok(meta) if meta.is_file() => Self::of_file(path, &meta),
            Ok(meta) if meta.is_dir() => Some(Identity::Path(normalised(path))),
            Ok(_) => None,
            // Not there yet (or a dangling link): where it would be created.
            Err(_) => Some(Identity::Path(normalised(
                &resolve_links(path).unwrap_or_else(|_| path.to_path_buf()),
            ))),
        }
    }

    #[cfg(unix)]
    fn of_file(_path: &Path, meta: &std::fs::Metadata) -> Option<Identity> {
        use std::os::unix::fs::MetadataExt;
        Some(Identity::File {
            dev: meta.dev(),
            ino: meta.ino(),
        })
    }

    #[cfg(not(unix))]
    fn of_file(path: &Path, _meta: &std::fs::Metadata) -> Option<Identity> {
        Some(Identity::Path(
            std::fs::canonicalize(path).unwrap_or_else(|_| normalised(path)),
        ))
    }

    /// Standard input when it is a regular file (`touchc inspect - < s.touch`).
    #[cfg(unix)]
    fn of_stdin() -> Option<Identity> {
        use std::os::fd::AsFd;
        let fd = io::stdin().as_fd().try_clone_to_owned().ok()?;
        let meta = File::from(fd).metadata().ok()?;
        meta.is_file()
            .then(|| Self::of_file(Path::new("-"), &meta))?
    }

    #[cfg(not(unix))]
    fn of_stdin() -> Option<Identity> {
        None
    }
}

/// `path` made absolute, its directory canonical where it exists, `.` and `..` folded
/// otherwise: two spellings of a file that does not exist yet compare equal.
fn normalised(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(path))
            .unwrap_or_else(|_| path.to_path_buf())
    };
    if let (Some(dir), Some(name)) = (absolute.parent(), absolute.file_name()) {
        if let Ok(dir) = std::fs::canonicalize(dir) {
            return dir.join(name);
        }
    }
    let mut out = PathBuf::new();
    for part in absolute.components() {
        match part {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// Mode 0666: the kernel filters it through the umask, as for any new file.
#[cfg(unix)]
fn new_file_permissions() -> Permissions {
    use std::os::unix::fs::PermissionsExt;
    Permissions::from_mode(0o666)
}

/// When this process began writing: temporaries older than this belong to other runs.
fn run_start() -> SystemTime {
    static START: OnceLock<SystemTime> = OnceLock::new();
    *START.get_or_init(SystemTime::now)
}

/// How much older than this run a temporary must be to count as another run's. File
/// times come from the kernel's coarse clock, which can lag `SystemTime::now()` by a
/// tick: without a margin a sibling thread's temporary, created just after the run
/// began and not yet locked, could look old and be removed under it.
const STALE_MARGIN: Duration = Duration::from_secs(2);

/// Removes `.touchc-*.tmp` files in `dir` left by killed runs: last written at least
/// [`STALE_MARGIN`] before `start` and not locked (a live writer holds its temporary's
/// lock until it closes it). Failures are ignored: cleaning is a courtesy, never a
/// reason to refuse a write.
fn remove_stale_temporaries(dir: &Path, start: SystemTime) {
    let Some(cutoff) = start.checked_sub(STALE_MARGIN) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if !(name.starts_with(TMP_PREFIX) && name.ends_with(TMP_SUFFIX)) {
            continue;
        }
        let Ok(meta) = entry.metadata() else { continue };
        let old = meta.modified().is_ok_and(|m| m < cutoff);
        if !meta.is_file() || !old {
            continue;
        }
        let path = entry.path();
        let Ok(file) = OpenOptions::new().read(true).open(&path) else {
            continue;
        };
        if file.try_lock().is_ok() {
            let _ = std::fs::remove_file(&path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_whole_file_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.touch");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn missing_directory_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/out.touch");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("out.touch"), "{err}");
        assert!(!path.exists());
    }

    #[test]
    fn an_unfinished_output_leaves_the_target_alone() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        std::fs::write(&path, b"old").unwrap();
        let mut out = Output::create(&path).unwrap();
        out.write_all(b"new, half").unwrap();
        drop(out);
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn locked_temporaries_are_kept_and_unlocked_old_ones_removed() {
        let dir = tempfile::tempdir().unwrap();
        let live = dir.path().join(".touchc-live.tmp");
        let dead = dir.path().join(".touchc-dead.tmp");
        let other = dir.path().join(".other.tmp");
        for p in [&live, &dead, &other] {
            std::fs::write(p, b"partial").unwrap();
        }
        let fresh = dir.path().join(".touchc-fresh.tmp");
        std::fs::write(&fresh, b"just created").unwrap();
        // Both temporaries must predate the run by the margin to be candidates at all.
        let long_ago = SystemTime::now() - 10 * STALE_MARGIN;
        for p in [&live, &dead, &other] {
            let f = OpenOptions::new().write(true).open(p).unwrap();
            f.set_modified(long_ago).unwrap();
        }
        let held = File::open(&live).unwrap();
        held.lock().unwrap();
        remove_stale_temporaries(dir.path(), SystemTime::now());
        assert!(live.exists(), "a locked temporary belongs to a live run");
        assert!(
            !dead.exists(),
            "an unlocked old temporary is a killed run's"
        );
        assert!(other.exists(), "only our own pattern is touched");
        assert!(
            fresh.exists(),
            "a temporary younger than the margin may be a sibling's, not yet locked"
        );
    }
}
