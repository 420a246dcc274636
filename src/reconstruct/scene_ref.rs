//! Which scene a name means: a folder, a real DTU scan under the data root, or a built-in
//! synthetic scene (generated once into the cache).

use super::ReconstructError;
use crate::scene::dtu;
use crate::sim::{self, SimError};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Where a scene came from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// A folder given by path.
    #[default]
    Folder,
    /// A DTU scan under the data root.
    Dtu,
    /// A built-in synthetic scene (generated into the cache).
    Builtin,
}

/// A resolved scene: its folder and a short name for output folders.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct ResolvedScene {
    pub dir: PathBuf,
    pub name: String,
    pub kind: SceneKind,
}

/// Resolves a scene name: a folder; `<data_root>/<name>` or
/// `<data_root>/dtu_<name>`; a built-in synthetic scene (generated once into the cache). An
/// empty name is the embedded default scene.
///
/// A folder in the working directory that holds no scene (no `cameras_sphere.npz`) does not
/// shadow a DTU scan or a built-in scene of the same bare name: `neus-aug reconstruct torus`
/// run beside a folder `torus/` of the user's own files trains the built-in `torus`, with a
/// warning that names the folder. A name written as a path (`./torus`, `runs/torus`,
/// `/data/torus`) is always the folder.
pub fn resolve_scene(
    spec: &str,
    data_root: &Path,
    quiet: bool,
) -> Result<ResolvedScene, ReconstructError> {
    let name = if spec.is_empty() { "default" } else { spec };
    let as_path = Path::new(name);
    let short = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| name.to_string())
    };
    if as_path.is_dir() {
        match shadowed_by_folder(as_path, name, data_root) {
            None => {
                return Ok(ResolvedScene {
                    dir: as_path.into(),
                    name: short(as_path),
                    kind: SceneKind::Folder,
                })
            }
            Some(what) => eprintln!(
                "warning: the folder {name} holds no {}, so '{name}' is taken as {what}; \
                 write ./{name} to load the folder",
                dtu::CAMERA_FILE
            ),
        }
    }
    if let Some(dir) = dtu_scan_dir(data_root, name) {
        return Ok(ResolvedScene {
            name: short(&dir),
            dir,
            kind: SceneKind::Dtu,
        });
    }
    match sim::builtin(name) {
        Ok(_) => {
            let root = sim::default_cache_root()?;
            if !quiet {
                eprintln!(
                    "scene '{name}': built-in synthetic scene (cache {})",
                    root.display()
                );
            }
            let dir = sim::ensure_builtin(name, &root)?;
            Ok(ResolvedScene {
                dir,
                name: name.to_string(),
                kind: SceneKind::Builtin,
            })
        }
        Err(SimError::UnknownScene { known, .. }) => Err(ReconstructError::SceneNotFound {
            name: name.into(),
            root: data_root.display().to_string(),
            known,
        }),
        Err(e) => Err(e.into()),
    }
}

/// What a bare scene `name` resolves to instead of the folder `dir` it names (`dir` is `name`
/// read from the working directory), when that folder holds no scene (no
/// `cameras_sphere.npz`) and the name is not written as a path. A path is absolute, has a
/// separator inside or at the end, or is `.` or `..`. `Some` names the scan under the data
/// root or the built-in scene that takes precedence (see [`resolve_scene`]); `None` keeps the
/// folder: a scene, a path, or a name of nothing else (the loader then says what it lacks).
fn shadowed_by_folder(dir: &Path, name: &str, data_root: &Path) -> Option<String> {
    let typed = Path::new(name);
    let mut parts = typed.components();
    let bare = matches!(
        (parts.next(), parts.next()),
        (Some(std::path::Component::Normal(_)), None)
    );
    let written_as_path = !bare || name.ends_with('/') || name.ends_with(std::path::MAIN_SEPARATOR);
    if written_as_path || dir.join(dtu::CAMERA_FILE).is_file() {
        return None;
    }
    if let Some(c) = dtu_scan_dir(data_root, name) {
        return Some(format!("the scan {}", c.display()));
    }
    sim::builtin(name)
        .ok()
        .map(|_| format!("the built-in synthetic scene '{name}'"))
}

/// The DTU scan folder `name` names under `data_root`: `<data_root>/<name>`, else
/// `<data_root>/dtu_<name>`, when it is a folder.
fn dtu_scan_dir(data_root: &Path, name: &str) -> Option<PathBuf> {
    [data_root.join(name), data_root.join(format!("dtu_{name}"))]
        .into_iter()
        .find(|c| c.is_dir())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folder-or-scene decision of [`resolve_scene`]: a folder without `cameras_sphere.npz`
    /// gives way to a DTU scan or built-in scene of the same bare name, and only to them.
    #[test]
    fn a_folder_that_holds_no_scene_does_not_shadow_a_scene_of_its_name() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().join("dtu");
        std::fs::create_dir_all(root.join("dtu_scan7")).unwrap();
        // The user's own folders, one named like a DTU scan, one like a built-in scene.
        let (scan, cup) = (tmp.path().join("scan7"), tmp.path().join("cup"));
        for d in [&scan, &cup] {
            std::fs::create_dir_all(d).unwrap();
            std::fs::write(d.join("notes.txt"), "mine").unwrap();
        }
        // `dir` is where the folder is; `name` is the scene name as the user typed it.
        let with_base = |name: &str| shadowed_by_folder(&tmp.path().join(name), name, &root);
        assert!(with_base("scan7").unwrap().contains("dtu_scan7"));
        assert!(with_base("cup")
            .unwrap()
            .contains("built-in synthetic scene 'cup'"));
        // A name of nothing else keeps the folder (the loader names what it lacks).
        std::fs::create_dir_all(tmp.path().join("mine")).unwrap();
        assert_eq!(with_base("mine"), None);
        // A folder that holds a scene wins.
        std::fs::write(cup.join(dtu::CAMERA_FILE), b"").unwrap();
        assert_eq!(with_base("cup"), None);
        std::fs::remove_file(cup.join(dtu::CAMERA_FILE)).unwrap();
        // A name written as a path is the folder, whatever else it names.
        for written in ["./cup", "cup/", cup.to_str().unwrap()] {
            assert_eq!(shadowed_by_folder(&cup, written, &root), None, "{written}");
        }
        // `.` names the working directory, not the data root (which `root.join(".")` is).
        assert_eq!(shadowed_by_folder(&cup, ".", &root), None);
        assert_eq!(shadowed_by_folder(&cup, "..", &root), None);
    }
}
