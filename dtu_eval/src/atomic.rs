//! The one way this workspace writes an output file: [`write_atomic`] (and [`write_atomic_with`]
//! for streaming writers). Used by `dtu-eval` (reports, arrays) and by `neus-aug` (run outputs,
//! checkpoints, study tables); it lives here because `dtu_eval` is the crate both depend on.
//!
//! The bytes go to a new temporary file in the target's own folder (so the final rename is atomic
//! on one file system); every write is checked, the file is `fsync`ed, and only then renamed over
//! the target. A reader, a crash or a full disk therefore never leaves half a file under the
//! target's name: either the old content or the complete new one. A target that exists but is not
//! a regular file (a FIFO, a device, a symbolic link, a folder) is refused, never replaced.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Refuses a `path` that exists and is not a regular file (symbolic links are not followed):
/// replacing a FIFO, a device or a link by a regular file would silently break whatever the user
/// connected there. A missing `path` is fine.
pub fn check_replaceable(path: &Path) -> io::Result<()> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    };
    let ft = meta.file_type();
    if ft.is_file() {
        return Ok(());
    }
    let what = if ft.is_symlink() {
        "a symbolic link"
    } else if ft.is_dir() {
        "a folder"
    } else {
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
    };
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("it is {what}, not a regular file; refusing to replace it (choose another path)"),
    ))
}

/// A temporary sibling name, unique within this process and across processes.
fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(
        ".tmp{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    path.with_file_name(name)
}

/// Writes what `fill` produces to `path` atomically (see the module docs). The parent folder must
/// exist. On any error the temporary file is removed and `path` is left as it was.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    check_replaceable(path)?;
    let tmp = temp_path(path);
    let result = (|| {
        let file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        fill(&mut w)?;
        let file: File = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        // Checked again: the target may have been replaced while the data was written.
        check_replaceable(path)?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `bytes` to `path` atomically (see the module docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Test fixture shared by the unit and command-line tests of the writers (this crate's and
/// neus-aug's): special files an output path may name, and the check that a refused write left
/// them as they were. Unix only (`mkfifo`, symbolic links).
#[doc(hidden)]
#[cfg(unix)]
pub mod special_files {
    use std::path::{Path, PathBuf};

    /// A FIFO, a regular file holding `keep`, and a symbolic link to that file, all in one folder.
    pub struct SpecialFiles {
        pub fifo: PathBuf,
        pub target: PathBuf,
        pub link: PathBuf,
    }

    impl SpecialFiles {
        /// Makes them in `dir` (panics when `mkfifo` or the link fails: a test fixture).
        pub fn make(dir: &Path) -> Self {
            let fifo = dir.join("special.fifo");
            let made = std::process::Command::new("mkfifo")
                .arg(&fifo)
                .status()
                .expect("mkfifo runs");
            assert!(made.success(), "mkfifo {}", fifo.display());
            let target = dir.join("kept.json");
            std::fs::write(&target, b"keep").unwrap();
            let link = dir.join("link.json");
            std::os::unix::fs::symlink(&target, &link).unwrap();
            Self { fifo, target, link }
        }

        /// Panics unless the FIFO is still a FIFO, the link still a link, the file still `keep`.
        pub fn assert_intact(&self) {
            use std::os::unix::fs::FileTypeExt;
            let kind = |p: &Path| std::fs::symlink_metadata(p).unwrap().file_type();
            assert!(kind(&self.fifo).is_fifo(), "the FIFO was replaced");
            assert!(kind(&self.link).is_symlink(), "the link was replaced");
            assert_eq!(std::fs::read(&self.target).unwrap(), b"keep");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_replaces_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.json");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "a temporary file was left behind");
    }

    #[test]
    fn a_failed_fill_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, b"old").unwrap();
        let e = write_atomic_with(&p, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("disk full"));
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn refuses_fifo_symlink_and_folder() {
        let dir = tempfile::tempdir().unwrap();
        let sp = special_files::SpecialFiles::make(dir.path());
        let (fifo, link) = (&sp.fifo, &sp.link);
        let folder = dir.path().join("folder");
        std::fs::create_dir(&folder).unwrap();
        for (p, what) in [(fifo, "FIFO"), (link, "symbolic link"), (&folder, "folder")] {
            let e = write_atomic(p, b"x").unwrap_err().to_string();
            assert!(e.contains(what) && e.contains("refusing"), "{e}");
        }
        sp.assert_intact();
        // Only the four entries made above: no temporary left.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4);
        let e = write_atomic(Path::new("/dev/null"), b"x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("device"), "{e}");
    }
}
