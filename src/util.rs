//! Small helpers shared by every layer. Imports nothing from the crate, so any module may use it.

use std::path::{Path, PathBuf};

/// FNV-1a, 64-bit offset basis (Fowler, Noll & Vo; IETF draft-eastlake-fnv, §2).
const FNV64_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a, 64-bit prime `2^40 + 2^8 + 0xb3`.
const FNV64_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a (64 bit) of `bytes`: a stable, non-cryptographic hash for names and seeds that must not
/// change between builds or platforms. Stored values depend on it bit for bit: the training hash
/// in `metrics.json` and checkpoints (`RunConfig::training_hash`), the scene cache folder names
/// (`sim::cache_key`), the study plan's configuration hashes and the bootstrap seeds.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv1a64::default();
    h.write(bytes);
    h.0
}

/// [`fnv1a64`] fed in pieces: the hash of the pieces' concatenation, without holding it.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a64(pub u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self(FNV64_OFFSET)
    }
}

impl Fnv1a64 {
    /// Feeds `bytes`.
    pub fn write(&mut self, bytes: &[u8]) {
        self.0 = bytes
            .iter()
            .fold(self.0, |h, &b| (h ^ b as u64).wrapping_mul(FNV64_PRIME));
    }

    /// The hash so far as 16 lower-case hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// [`fnv1a64`] as 16 lower-case hex digits, zero padded (the form written to files).
pub fn fnv1a64_hex(bytes: &[u8]) -> String {
    format!("{:016x}", fnv1a64(bytes))
}

/// What an output folder (`--out DIR`) holds before a command writes into it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputDir {
    /// Nothing is there (and no link either): the command creates the folder.
    Absent,
    /// An empty folder, or a symbolic link to one.
    Empty,
    /// A folder with entries (each command says whether it may write there).
    NotEmpty,
}

/// Why a path cannot be an output folder. Every variant names the path.
#[derive(Debug, thiserror::Error)]
pub enum OutputDirError {
    /// A symbolic link whose target does not exist: creating the folder would fail with the
    /// operating system's bare "File exists".
    #[error(
        "{path} is a symbolic link to {target}, which does not exist; create that folder or \
         remove the link"
    )]
    DanglingLink { path: PathBuf, target: PathBuf },
    /// Something other than a folder (a file, or a link to one).
    #[error("{path} exists and is not a folder{link}", link = if *.link { " (it is a symbolic link to one that is not)" } else { "" })]
    NotAFolder { path: PathBuf, link: bool },
    /// The path or its target cannot be examined or listed.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Examines `path` as an output folder without changing anything: absent, empty or not, or an
/// error naming what is wrong (a dangling symbolic link, a file, an unreadable folder). A link to
/// a folder counts as that folder. Shared by every command that takes `--out`.
pub fn inspect_output_dir(path: &Path) -> Result<OutputDir, OutputDirError> {
    let io = |source| OutputDirError::Io {
        path: path.into(),
        source,
    };
    let link = match std::fs::symlink_metadata(path) {
        Ok(m) => m.file_type().is_symlink(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(OutputDir::Absent),
        Err(e) => return Err(io(e)),
    };
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if link && e.kind() == std::io::ErrorKind::NotFound => {
            return Err(OutputDirError::DanglingLink {
                path: path.into(),
                target: std::fs::read_link(path).map_err(io)?,
            })
        }
        Err(e) => return Err(io(e)),
    };
    if !meta.is_dir() {
        return Err(OutputDirError::NotAFolder {
            path: path.into(),
            link,
        });
    }
    let mut entries = std::fs::read_dir(path).map_err(io)?;
    Ok(if entries.next().is_some() {
        OutputDir::NotEmpty
    } else {
        OutputDir::Empty
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a64_matches_published_vectors() {
        // Test vectors of the FNV reference (draft-eastlake-fnv, appendix C).
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn hashes_stay_those_of_the_code_before_the_merge() {
        // Computed with the two implementations the project first had
        // (`reconstruct::config` training_hash and `scene::sim::fnv1a64`); both agreed. Stored
        // training hashes (checkpoints, metrics.json) and cache folders rely on these bits.
        let toml = "scene = \"blob\"\nseed = 0\n\n[train]\niterations = 2000\n";
        assert_eq!(fnv1a64_hex(toml.as_bytes()), "6c6cdba731985532");
        assert_eq!(fnv1a64(b"table2/blob/sia"), 0x0d97_016e_8508_ed67);
        // Zero padding: a leading zero digit is kept.
        assert_eq!(fnv1a64_hex(b"table2/blob/sia"), "0d97016e8508ed67");
        // In pieces: the hash of the concatenation.
        let mut h = Fnv1a64::default();
        h.write(b"table2/");
        h.write(b"blob/sia");
        assert_eq!(h.hex(), "0d97016e8508ed67");
    }

    #[test]
    fn output_dir_states_and_errors_name_the_path() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        assert_eq!(
            inspect_output_dir(&d.join("new")).unwrap(),
            OutputDir::Absent
        );
        std::fs::create_dir(d.join("empty")).unwrap();
        assert_eq!(
            inspect_output_dir(&d.join("empty")).unwrap(),
            OutputDir::Empty
        );
        std::fs::create_dir(d.join("full")).unwrap();
        std::fs::write(d.join("full/x"), "x").unwrap();
        assert_eq!(
            inspect_output_dir(&d.join("full")).unwrap(),
            OutputDir::NotEmpty
        );
        std::os::unix::fs::symlink(d.join("empty"), d.join("to-empty")).unwrap();
        assert_eq!(
            inspect_output_dir(&d.join("to-empty")).unwrap(),
            OutputDir::Empty
        );
        std::os::unix::fs::symlink(d.join("gone"), d.join("dangling")).unwrap();
        let e = inspect_output_dir(&d.join("dangling"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("dangling") && e.contains("gone") && e.contains("symbolic link"),
            "{e}"
        );
        std::fs::write(d.join("file"), "x").unwrap();
        let e = inspect_output_dir(&d.join("file")).unwrap_err().to_string();
        assert!(e.contains("file") && e.contains("not a folder"), "{e}");
        std::os::unix::fs::symlink(d.join("file"), d.join("to-file")).unwrap();
        let e = inspect_output_dir(&d.join("to-file"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("symbolic link"), "{e}");
    }
}
