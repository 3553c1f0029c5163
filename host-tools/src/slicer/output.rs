//! Writing outputs so that nothing half-written is ever left: each file is written to a
//! temporary file in the destination's directory and renamed over it only once complete;
//! a command with several outputs stages them all first and renames them together
//! ([`StagedFiles`]), so a failure on one leaves none. Existing symlinks, FIFOs, devices and
//! directories at an output path are refused rather than replaced. Temporary files are
//! registered so that Ctrl-C removes them. Also the progress bars, shown on a terminal
//! and silent when stderr is piped.

use super::error::SliceError;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

/// Temporary files in flight, removed by the Ctrl-C handler.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static HANDLER: Once = Once::new();

/// Exit status after Ctrl-C (128 + SIGINT), as shells report it.
const INTERRUPTED: i32 = 130;

fn register(p: &Path) {
    HANDLER.call_once(|| {
        // Another handler (the link commands' pause on Ctrl-C) may own the signal; those
        // commands write no outputs, so failing to install is harmless.
        let _ = ctrlc::set_handler(|| {
            remove_pending();
            eprintln!("dollop: interrupted; temporary files removed, nothing written");
            std::process::exit(INTERRUPTED);
        });
    });
    if let Ok(mut v) = PENDING.lock() {
        v.push(p.to_path_buf());
    }
}

fn unregister(p: &Path) {
    if let Ok(mut v) = PENDING.lock() {
        v.retain(|x| x != p);
    }
}

/// Removes every temporary file in flight (what Ctrl-C does before exiting).
pub fn remove_pending() {
    if let Ok(mut v) = PENDING.lock() {
        for p in v.drain(..) {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Temporary files in flight (for tests).
pub fn pending() -> Vec<PathBuf> {
    PENDING.lock().map(|v| v.clone()).unwrap_or_default()
}

/// The I/O error without the temporary file's path, which the `tempfile` crate puts in
/// its messages: the user should see their own file named, not `.dollop-XXXX.part`.
fn plain(e: std::io::Error) -> std::io::Error {
    if let Some(code) = e.raw_os_error() {
        return std::io::Error::from_raw_os_error(code);
    }
    // tempfile wraps the OS error in its own error carrying the path; unwrap it.
    let code = e
        .get_ref()
        .and_then(|inner| inner.source())
        .and_then(|src| src.downcast_ref::<std::io::Error>())
        .and_then(std::io::Error::raw_os_error);
    match code {
        Some(code) => std::io::Error::from_raw_os_error(code),
        None if e.to_string().contains(".part") => std::io::Error::from(e.kind()),
        None => e,
    }
}

/// Refuses to replace anything but a regular file: writing "over" a symlink, FIFO or
/// device would either follow it somewhere unexpected or destroy it.
pub fn check_target(path: &Path) -> std::io::Result<()> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(plain(e)),
    };
    let ft = meta.file_type();
    if ft.is_file() {
        return Ok(());
    }
    let what = if ft.is_symlink() {
        "a symbolic link"
    } else if ft.is_dir() {
        "a directory"
    } else {
        kind_of_special(&ft)
    };
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!("is {what}; dollop only replaces regular files (remove it or choose another path)"),
    ))
}

#[cfg(unix)]
fn kind_of_special(ft: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_fifo() {
        "a FIFO"
    } else if ft.is_char_device() || ft.is_block_device() {
        "a device"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

#[cfg(not(unix))]
fn kind_of_special(_: &std::fs::FileType) -> &'static str {
    "not a regular file"
}

/// One staged output: complete in its temporary file, not yet renamed.
struct Staged {
    path: PathBuf,
    tmp: tempfile::TempPath,
}

/// Files written together or not at all: [`StagedFiles::stage`] each (a temporary file
/// beside the destination, written and synced), then [`StagedFiles::commit`] renames them
/// all. Dropping it uncommitted removes the temporary files.
#[derive(Default)]
pub struct StagedFiles {
    staged: Vec<Staged>,
}

impl StagedFiles {
    /// No outputs yet.
    pub fn new() -> Self {
        StagedFiles::default()
    }

    /// Writes `path`'s content through `fill` into a temporary file beside it. Errors are
    /// the I/O error as it is, without the temporary name.
    pub fn stage(
        &mut self,
        path: &Path,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        check_target(path)?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let tmp = tempfile::Builder::new()
            .prefix(".dollop-")
            .suffix(".part")
            .tempfile_in(dir)
            .map_err(plain)?;
        let (mut file, tmp) = tmp.into_parts();
        register(&tmp);
        // From here the TempPath removes the file on any early return.
        let staged = Staged {
            path: path.to_path_buf(),
            tmp,
        };
        let result = (|| {
            {
                let mut w = BufWriter::new(&mut file);
                fill(&mut w)?;
                w.flush()?;
            }
            // Temporary files are private (0600); outputs are ordinary files.
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let mode =
                    std::fs::metadata(path).map_or(0o644, |m| m.permissions().mode() & 0o7777);
                file.set_permissions(std::fs::Permissions::from_mode(mode))?;
            }
            file.sync_all()
        })();
        if let Err(e) = result {
            unregister(&staged.tmp);
            return Err(plain(e));
        }
        self.staged.push(staged);
        Ok(())
    }

    /// Renames every staged file over its destination. On failure, names the output.
    pub fn commit(mut self) -> Result<(), (PathBuf, std::io::Error)> {
        // Check every destination again before the first rename, so a refusal leaves all.
        for s in &self.staged {
            check_target(&s.path).map_err(|e| (s.path.clone(), e))?;
        }
        for s in self.staged.drain(..) {
            let Staged { path, tmp } = s;
            let name = tmp.to_path_buf();
            let r = tmp.persist(&path);
            unregister(&name);
            r.map_err(|e| (path.clone(), plain(e.error)))?;
        }
        Ok(())
    }
}

impl Drop for StagedFiles {
    fn drop(&mut self) {
        for s in &self.staged {
            unregister(&s.tmp);
        }
        // The TempPaths remove their files as they drop.
    }
}

/// Writes `path` through `fill`, atomically: on any error the destination is untouched
/// and the temporary file is removed.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), SliceError> {
    write_file_atomically(path, fill).map_err(|source| SliceError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// `write_atomic` with the I/O error as it is, for callers with their own error type.
pub fn write_file_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut out = StagedFiles::new();
    out.stage(path, fill)?;
    out.commit().map_err(|(_, e)| e)
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), SliceError> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Stages `path` in `out`, with the slicer's error naming the user's file.
pub fn stage(
    out: &mut StagedFiles,
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), SliceError> {
    out.stage(path, fill).map_err(|source| SliceError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Commits `out`, with the slicer's error naming the user's file.
pub fn commit(out: StagedFiles) -> Result<(), SliceError> {
    out.commit()
        .map_err(|(path, source)| SliceError::Write { path, source })
}

/// How often a pipe gets a progress line.
pub const PIPE_PROGRESS_EVERY: std::time::Duration = std::time::Duration::from_secs(5);

/// Progress on a stderr that is not a terminal (a pipe, a log file, CI): a plain line every
/// [`PIPE_PROGRESS_EVERY`], the first after that long (work shorter than that stays quiet),
/// never cursor movement.
#[derive(Debug)]
struct PipeLines {
    last: Mutex<std::time::Instant>,
}

impl indicatif::TermLike for PipeLines {
    fn width(&self) -> u16 {
        100
    }
    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, line: &str) -> std::io::Result<()> {
        let now = std::time::Instant::now();
        let mut last = self.last.lock().unwrap_or_else(|p| p.into_inner());
        if line.trim().is_empty() || now - *last < PIPE_PROGRESS_EVERY {
            return Ok(());
        }
        *last = now;
        writeln!(std::io::stderr(), "{}", line.trim_end())
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.write_line(s)
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

/// A progress bar of `len` steps labelled `what` on stderr: drawn when stderr is a
/// terminal, a plain line every few seconds otherwise (pipes, logs, CI), so a long run is
/// never silent.
pub fn progress(len: u64, what: &str) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::with_draw_target(
            Some(len),
            indicatif::ProgressDrawTarget::term_like_with_hz(
                Box::new(PipeLines {
                    last: Mutex::new(std::time::Instant::now()),
                }),
                1,
            ),
        );
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{msg}: {pos}/{len} ({percent} %, {elapsed} so far, about {eta} left)",
        ) {
            bar.set_style(style);
        }
        bar.set_message(what.to_string());
        return bar;
    }
    let bar = indicatif::ProgressBar::new(len);
    let style = indicatif::ProgressStyle::with_template(
        "{msg:>12} [{bar:40}] {pos}/{len} ({elapsed}, {eta} left)",
    )
    .map(|s| s.progress_chars("=> "))
    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(what.to_string());
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_leaves_neither_the_file_nor_a_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.dlp");
        let e = write_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("disk full"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_bytes(&path, b"whole").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"whole");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(pending().iter().all(|p| !p.starts_with(dir.path())));
    }

    #[test]
    fn outputs_are_all_written_or_none_and_errors_name_the_users_file() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.dlp");
        let b = dir.path().join("missing").join("b.png");
        let mut out = StagedFiles::new();
        out.stage(&a, |w| w.write_all(b"job")).unwrap();
        let e = stage(&mut out, &b, |w| w.write_all(b"png")).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with(&format!("{}: cannot write", b.display())),
            "{msg}"
        );
        assert!(!msg.contains(".part"), "{msg}");
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn symlinks_and_fifos_are_refused_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("real");
        std::fs::write(&target, b"keep").unwrap();
        let link = dir.path().join("link.dlp");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let e = write_bytes(&link, b"new").unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&target).unwrap(), b"keep");
        let e = write_bytes(Path::new("/dev/null"), b"x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a device"), "{e}");
        let fifo = dir.path().join("fifo");
        let ok = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            let e = write_bytes(&fifo, b"x").unwrap_err().to_string();
            assert!(e.contains("a FIFO"), "{e}");
        }
    }
}
