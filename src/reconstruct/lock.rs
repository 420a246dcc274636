//! The lock of a run folder: `<out>/.neus-aug-run.lock`, held (`flock`, exclusive) by the one
//! process writing the run, for the whole run.
//!
//! The file stays in the folder, and it marks the folder as a neus-aug run. While a process holds
//! the lock the file contains its pid, so a second writer is refused with a message naming the
//! holder. The kernel releases an `flock` when its holder dies, however it dies; a pid still in an
//! unlocked file is therefore that of a run that ended without releasing it (killed), and the lock
//! is simply taken over ([`RunLock::previous`] reports that pid). A run that ends normally empties
//! the file.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

/// Name of the lock file inside a run folder.
pub const LOCK_FILE: &str = ".neus-aug-run.lock";

/// Why a run folder cannot be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another process holds the lock.
    #[error(
        "output folder {dir} is in use by another neus-aug process ({holder}, holding {lock}); \
         wait for it to finish or choose another --out"
    )]
    Held {
        dir: PathBuf,
        lock: PathBuf,
        holder: String,
    },
    /// The lock file could not be opened or locked.
    #[error("cannot lock {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// The held lock of a run folder; released (and its pid erased) when dropped.
#[derive(Debug)]
pub struct RunLock {
    file: File,
    /// The pid a previous holder left in the file: a run that ended without releasing the lock
    /// (killed), whose lock this one took over. `None` when the file was empty or new.
    pub previous: Option<u32>,
}

fn holder_text(pid: Option<u32>) -> String {
    match pid {
        Some(p) => format!("pid {p}"),
        None => "pid not yet recorded".to_string(),
    }
}

fn read_pid(file: &mut File) -> Option<u32> {
    let mut text = String::new();
    file.rewind().ok()?;
    file.read_to_string(&mut text).ok()?;
    text.trim().parse().ok()
}

/// `flock(fd, op | LOCK_NB)`: `Ok(true)` when taken, `Ok(false)` when another holder has it.
fn try_flock(file: &File, op: i32) -> std::io::Result<bool> {
    // SAFETY: flock on a file descriptor this `File` owns and keeps open.
    let rc = unsafe { libc::flock(file.as_raw_fd(), op | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(false)
    } else {
        Err(e)
    }
}

impl RunLock {
    /// Takes the lock of `dir` (which must exist), or fails at once naming the holder's pid.
    pub fn acquire(dir: &Path) -> Result<RunLock, LockError> {
        let path = dir.join(LOCK_FILE);
        let io = |source| LockError::Io {
            path: path.clone(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        if !try_flock(&file, libc::LOCK_EX).map_err(io)? {
            return Err(LockError::Held {
                dir: dir.into(),
                holder: holder_text(read_pid(&mut file)),
                lock: path,
            });
        }
        let previous = read_pid(&mut file).filter(|&p| p != std::process::id());
        file.set_len(0)
            .and_then(|_| file.rewind())
            .and_then(|_| writeln!(file, "{}", std::process::id()))
            .and_then(|_| file.flush())
            .map_err(io)?;
        Ok(RunLock { file, previous })
    }

    /// Fails (naming the holder) when another process holds the lock of `dir` now; takes nothing.
    pub fn check_free(dir: &Path) -> Result<(), LockError> {
        let path = dir.join(LOCK_FILE);
        let mut file = match File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(source) => return Err(LockError::Io { path, source }),
        };
        match try_flock(&file, libc::LOCK_SH) {
            Ok(true) => Ok(()), // released when `file` closes
            Ok(false) => Err(LockError::Held {
                dir: dir.into(),
                holder: holder_text(read_pid(&mut file)),
                lock: path,
            }),
            Err(source) => Err(LockError::Io { path, source }),
        }
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        // A normal end erases the pid; the kernel releases the flock when the file closes.
        let _ = self.file.set_len(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_holder_is_refused_with_the_pid_and_a_dead_holder_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let a = RunLock::acquire(dir.path()).unwrap();
        assert_eq!(a.previous, None);
        let text = std::fs::read_to_string(dir.path().join(LOCK_FILE)).unwrap();
        assert_eq!(text.trim(), std::process::id().to_string());
        // A second open file description conflicts even within one process.
        let e = RunLock::acquire(dir.path()).unwrap_err().to_string();
        assert!(e.contains(&format!("pid {}", std::process::id())), "{e}");
        assert!(RunLock::check_free(dir.path()).is_err());
        drop(a);
        assert_eq!(
            std::fs::read_to_string(dir.path().join(LOCK_FILE)).unwrap(),
            "",
            "a normal release erases the pid"
        );
        RunLock::check_free(dir.path()).unwrap();
        // A pid left by a killed holder (file not locked): taken over and reported.
        std::fs::write(dir.path().join(LOCK_FILE), "999999999\n").unwrap();
        let b = RunLock::acquire(dir.path()).unwrap();
        assert_eq!(b.previous, Some(999_999_999));
    }
}
