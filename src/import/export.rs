//! Writing a scene's true cameras as a COLMAP text model or a transforms.json (`neus-aug synth
//! --export colmap|transforms`), so the importers can be tested against known cameras.
//!
//! The cameras are read back from the scene folder the simulator wrote: `world_mat_i` of
//! `cameras_sphere.npz` is `K·[R | −R·C]` of the simulator's world-space camera, decomposed here
//! with [`Camera::from_projection`] (exact to ~1e-13 relative; see [`clean_roundoff`]); the ground-truth points are
//! `Points/stl/*.ply`.

use super::colmap::{self, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint};
use super::transforms::{self, FrameOut};
use super::{io_err, ImportError};
use crate::scene::dtu::CAMERA_FILE;
use crate::scene::npz;
use crate::scene::Camera;
use nalgebra::{Matrix3x4, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Number of ground-truth points written as COLMAP `points3D` (evenly strided over the file).
pub const COLMAP_POINTS: usize = 300;

/// A scene's views: image and mask files and world-space cameras, in scene order.
pub struct SceneCameras {
    /// `image/*.png`, sorted by name (the order of `world_mat_i`).
    pub images: Vec<PathBuf>,
    /// `mask/{i:03}.png` when present for every view.
    pub masks: Option<Vec<PathBuf>>,
    /// World-space cameras.
    pub cameras: Vec<Camera>,
}

/// Reads the cameras of a scene folder written by [`crate::scene::write_scene`] (file names
/// `image/{i:06}.png`, `mask/{i:03}.png`).
pub fn read_scene_cameras(scene: &Path) -> Result<SceneCameras, ImportError> {
    let image_dir = scene.join("image");
    let mut images: Vec<PathBuf> = std::fs::read_dir(&image_dir)
        .map_err(io_err(&image_dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    images.sort();
    if images.is_empty() {
        return Err(ImportError::NoViews(image_dir));
    }
    let sizes = images
        .iter()
        .map(|img| {
            image::image_dimensions(img).map_err(|source| {
                ImportError::Image(crate::scene::ImageError::Decode {
                    path: img.clone(),
                    source,
                })
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut cameras = read_world_cameras(&scene.join(CAMERA_FILE), &sizes)?;
    clean_roundoff(&mut cameras);
    let masks: Vec<PathBuf> = (0..images.len())
        .map(|i| scene.join("mask").join(format!("{i:03}.png")))
        .collect();
    let masks = masks.iter().all(|m| m.is_file()).then_some(masks);
    Ok(SceneCameras {
        images,
        masks,
        cameras,
    })
}

/// The cameras `world_mat_0 … world_mat_{n−1}` of a `cameras_sphere.npz`-style file, view `i`
/// of size `sizes[i]` (`K·[R | −R·C]` decomposed with [`Camera::from_projection`]).
pub fn read_world_cameras(path: &Path, sizes: &[(u32, u32)]) -> Result<Vec<Camera>, ImportError> {
    let arrays = npz::read(path).map_err(crate::scene::SceneError::from)?;
    let mut cameras = Vec::with_capacity(sizes.len());
    for (i, &(w, h)) in sizes.iter().enumerate() {
        let key = format!("world_mat_{i}");
        let a = arrays
            .get(&key)
            .filter(|a| a.shape == [4, 4] || a.shape == [3, 4])
            .ok_or_else(|| ImportError::Parse {
                file: path.into(),
                message: format!("'{key}' is missing or not 4×4"),
            })?;
        let p = Matrix3x4::from_fn(|r, c| a.data[r * 4 + c]);
        let cam = Camera::from_projection(&p, w, h).map_err(|e| ImportError::Parse {
            file: path.into(),
            message: format!("'{key}': {e}"),
        })?;
        cameras.push(cam);
    }
    Ok(cameras)
}

/// Removes the decomposition's round-off from intrinsics: a skew below `1e-9·fx` becomes 0, and
/// intrinsics within `1e-10` (relative) of the first camera's become exactly the first's, so a
/// shared `K` is written once. The change is far below the importers' test tolerance.
fn clean_roundoff(cameras: &mut [Camera]) {
    for cam in cameras.iter_mut() {
        if cam.k[(0, 1)].abs() <= 1e-9 * cam.k[(0, 0)] {
            cam.k[(0, 1)] = 0.0;
        }
    }
    let Some(first) = cameras.first().cloned() else {
        return;
    };
    for cam in cameras.iter_mut() {
        let close = (cam.k - first.k).abs().max() <= 1e-10 * first.k.norm();
        if close && (cam.width, cam.height) == (first.width, first.height) {
            cam.k = first.k;
        }
    }
}

fn ground_truth_points(scene: &Path) -> Result<Vec<[f64; 3]>, ImportError> {
    let dir = scene.join("Points").join("stl");
    let mut plys: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(io_err(&dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ply"))
        .collect();
    plys.sort();
    let ply = plys.first().ok_or_else(|| ImportError::MissingFile {
        path: dir.join("stl*_total.ply"),
        what: "the ground-truth points of a synthetic scene".into(),
    })?;
    let pts = dtu_eval::ply::read_points(ply).map_err(|e| ImportError::Parse {
        file: ply.clone(),
        message: e.to_string(),
    })?;
    let stride = pts.len().div_ceil(COLMAP_POINTS).max(1);
    Ok(pts
        .iter()
        .step_by(stride)
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect())
}

/// Writes `out/sparse/0/{cameras,images,points3D}.txt` for the scene ([`colmap_model`]):
/// images named like the scene's `image/` files (so `--images <scene>/image` imports them), and
/// [`COLMAP_POINTS`] ground-truth points. Returns the model folder.
pub fn export_colmap(scene: &Path, out: &Path) -> Result<PathBuf, ImportError> {
    let sc = read_scene_cameras(scene)?;
    let points = ground_truth_points(scene)?;
    let names: Vec<String> = sc
        .images
        .iter()
        .map(|p| {
            p.file_name()
                .expect("a listed file")
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let model = colmap_model(&sc.cameras, &names, &points)?;
    let dir = out.join("sparse").join("0");
    colmap::write_text(&model, &dir)?;
    Ok(dir)
}

/// A COLMAP model of world-space `cameras` (image `i` named `names[i]`): PINHOLE cameras, one
/// per distinct intrinsics and size, and `points` whose tracks list the images they project
/// into (inside the image, in front of the camera; occlusion is not tested). A camera with skew
/// (beyond a decomposition's round-off, `1e-9·fx`) is refused: PINHOLE cannot hold it.
pub fn colmap_model(
    cameras: &[Camera],
    names: &[String],
    points: &[[f64; 3]],
) -> Result<ColmapModel, ImportError> {
    let mut model = ColmapModel::default();
    let mut camera_ids: Vec<(Camera, u32)> = Vec::new();
    for (i, cam) in cameras.iter().enumerate() {
        if cam.k[(0, 1)].abs() > 1e-9 * cam.k[(0, 0)] {
            return Err(ImportError::Export(format!(
                "view {i} has skew {}, which COLMAP's PINHOLE model cannot hold",
                cam.k[(0, 1)]
            )));
        }
        let same = |c: &Camera| c.k == cam.k && (c.width, c.height) == (cam.width, cam.height);
        let camera_id = match camera_ids.iter().find(|(c, _)| same(c)) {
            Some((_, id)) => *id,
            None => {
                let id = camera_ids.len() as u32 + 1;
                camera_ids.push((cam.clone(), id));
                model.cameras.insert(
                    id,
                    ColmapCamera {
                        id,
                        model: "PINHOLE".into(),
                        width: cam.width as u64,
                        height: cam.height as u64,
                        params: vec![cam.k[(0, 0)], cam.k[(1, 1)], cam.k[(0, 2)], cam.k[(1, 2)]],
                    },
                );
                id
            }
        };
        let t = -(cam.r * cam.center);
        model.images.push(ColmapImage {
            id: i as u32 + 1,
            qvec: colmap::quaternion(&cam.r),
            tvec: [t.x, t.y, t.z],
            camera_id,
            name: names[i].clone(),
            points2d: Vec::new(),
        });
    }
    let mut tracks: BTreeMap<u64, Vec<(u32, u32)>> = BTreeMap::new();
    for (j, p) in points.iter().enumerate() {
        let id = j as u64 + 1;
        for (i, cam) in cameras.iter().enumerate() {
            if let Some((u, v, _)) = cam.project(&Vector3::from(*p)) {
                if u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64 {
                    let im = &mut model.images[i];
                    tracks
                        .entry(id)
                        .or_default()
                        .push((im.id, im.points2d.len() as u32));
                    im.points2d.push((u, v, id as i64));
                }
            }
        }
    }
    for (j, p) in points.iter().enumerate() {
        let id = j as u64 + 1;
        model.points.push(ColmapPoint {
            id,
            xyz: *p,
            rgb: [128, 128, 128],
            error: 0.0,
            track: tracks.remove(&id).unwrap_or_default(),
        });
    }
    Ok(model)
}

/// Writes `out/transforms.json` for the scene (OpenGL poses, intrinsics shared when equal,
/// nerfstudio `mask_path` when the scene has masks). Paths are relative to `out` when `out` is
/// the scene folder, absolute otherwise. Returns the json path.
pub fn export_transforms(scene: &Path, out: &Path) -> Result<PathBuf, ImportError> {
    let sc = read_scene_cameras(scene)?;
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let same_dir = match (scene.canonicalize(), out.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let name = |p: &Path| -> String {
        if same_dir {
            p.strip_prefix(scene)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned()
        } else {
            std::path::absolute(p)
                .unwrap_or_else(|_| p.to_path_buf())
                .to_string_lossy()
                .into_owned()
        }
    };
    let frames: Vec<FrameOut> = sc
        .cameras
        .iter()
        .enumerate()
        .map(|(i, cam)| FrameOut {
            file_path: name(&sc.images[i]),
            mask_path: sc.masks.as_ref().map(|m| name(&m[i])),
            camera: cam,
        })
        .collect();
    let path = out.join("transforms.json");
    transforms::write_json(&path, &frames)?;
    Ok(path)
}
