//! The written scene is a DTU scene: it loads through the foundation's loader with the cameras,
//! masks and normalisation the simulator used; its ground-truth files read back (matfile, PLY)
//! to what was computed; the same description gives the same bytes (in any thread count); and the
//! built-in cache is atomic.

mod sim_common;

use dtu_eval::gt::{GtPaths, ObsMask, Plane};
use neus_aug::scene::{LoadOptions, Scene};
use neus_aug::sim::{self, GenerateOptions, SceneDescription, SimScene};
use sim_common::small;
use std::collections::BTreeMap;
use std::path::Path;

fn tiny() -> SceneDescription {
    small("blob", 64, 48, 5, 2, 2.0)
}

#[test]
fn a_written_scene_loads_with_its_cameras_masks_and_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("blob");
    let desc = tiny();
    let report = sim::generate(&desc, &root, &GenerateOptions::default()).unwrap();
    let sim_scene = SimScene::prepare(&desc).unwrap();

    let scene = Scene::load(&root, &LoadOptions::default()).unwrap();
    assert_eq!(scene.views.len(), 5);
    assert!(scene.scale_mats_consistent);
    let n = scene.normalization;
    assert!((n.scale - sim_scene.normalization.scale).abs() < 1e-9 * n.scale);
    for k in 0..3 {
        assert!((n.center[k] - sim_scene.normalization.center[k]).abs() < 1e-9);
    }
    // The object is inside the unit sphere, with the scale_mat margin to spare.
    let r_max = sim_scene
        .mesh_world
        .vertices
        .iter()
        .map(|v| {
            let p = n.to_normalized(v.map(|c| c as f64));
            (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
        })
        .fold(0.0, f64::max);
    assert!(
        (r_max - 1.0 / desc.rig.scale_margin).abs() < 1e-4,
        "object radius in normalised space {r_max}"
    );
    for (view, world_cam) in scene.views.iter().zip(&sim_scene.cameras) {
        let back = view
            .camera
            .denormalized(n.scale, &nalgebra::Vector3::from(n.center));
        assert!((back.center - world_cam.center).norm() < 1e-6);
        assert!((back.r - world_cam.r).norm() < 1e-9);
        assert!((back.k - world_cam.k).norm() < 1e-6);
        assert_eq!((view.image.width, view.image.height), (64, 48));
        let mask = view.mask.as_ref().expect("masks are written");
        // The rendered mask, exactly (0/255 PNG).
        let rendered = sim_scene.render_view(view.index).mask;
        assert_eq!(mask.data, rendered.data);
        assert!(mask.coverage() > 0.1);
    }

    // Ground truth reads back to what was computed, via matfile and the PLY reader.
    let gt = sim_scene.ground_truth();
    let paths = GtPaths::new(&root, desc.scan);
    assert_eq!(ObsMask::read(&paths.obs_mask).unwrap(), gt.obs_mask);
    assert_eq!(Plane::read(&paths.plane).unwrap(), gt.plane);
    assert_eq!(
        dtu_eval::ply::read_points(&paths.points).unwrap(),
        gt.points
    );
    assert_eq!(report.gt.visible as usize, gt.points.len());
    let mesh = dtu_eval::ply::read_mesh(&root.join("gt_mesh.ply")).unwrap();
    assert_eq!(mesh, sim_scene.mesh_world);
    // Every GT point lies above the plane and inside BB, in an observed voxel.
    for p in &gt.points {
        assert!(gt.plane.eval(p.map(|c| c as f64)) > 0.0);
        let idx = sim::gt::voxel_index(*p, gt.obs_mask.bb[0], gt.obs_mask.res);
        assert!(gt.obs_mask.get(idx[0], idx[1], idx[2]));
    }
    // The scene description and metadata.
    let back = SceneDescription::load(&root.join("scene.toml")).unwrap();
    assert_eq!(back, desc);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["scan"], 101);
    assert_eq!(meta["name"], "blob");
    assert_eq!(meta["gt"]["points"], gt.points.len() as u64);
    assert_eq!(meta["counters"]["primary_rays"], (5 * 64 * 48 * 2) as u64);
}

fn files(root: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn the_same_description_gives_the_same_bytes_in_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut desc = tiny();
    desc.effects.exposure = Some(Default::default());
    desc.effects.light_jitter = Some(Default::default());
    desc.effects.shadows = Some(Default::default());
    desc.effects.ground_plane = Some(Default::default());
    desc.effects.degrade = vec!["speckle:0.2".into(), "salt-pepper:0.01".into()];
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    sim::generate(&desc, &a, &GenerateOptions::default()).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    one.install(|| sim::generate(&desc, &b, &GenerateOptions::default()))
        .unwrap();
    let (fa, fb) = (files(&a), files(&b));
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    assert!(fa.len() >= 5 + 5 + 7, "{:?}", fa.keys());
    for (name, bytes) in &fa {
        if name == "timings.json" {
            continue;
        }
        assert!(bytes == &fb[name], "{name} differs between runs");
    }
    // A different seed changes the images (exposure, light, texture) but not the ground truth.
    let c = dir.path().join("c");
    let mut seeded = desc.clone();
    seeded.seed = 1;
    sim::generate(&seeded, &c, &GenerateOptions::default()).unwrap();
    let fc = files(&c);
    assert_ne!(fa["image/000000.png"], fc["image/000000.png"]);
    assert_eq!(
        fa["Points/stl/stl101_total.ply"],
        fc["Points/stl/stl101_total.ply"]
    );
}

#[test]
fn the_cache_generates_once_and_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let desc = small("torus", 32, 24, 2, 1, 3.0);
    // A killed earlier run left a temporary folder behind: it must not count as the scene.
    let stale = cache.join(format!(".{}.tmp-1-2", sim::cache_key(&desc)));
    std::fs::create_dir_all(stale.join("image")).unwrap();
    let first = sim::ensure_scene(&desc, &cache).unwrap();
    assert_eq!(first, cache.join(sim::cache_key(&desc)));
    assert!(first.join("meta.json").is_file() && first.join("cameras_sphere.npz").is_file());
    let stamp = std::fs::metadata(first.join("meta.json"))
        .unwrap()
        .modified()
        .unwrap();
    let again = sim::ensure_scene(&desc, &cache).unwrap();
    assert_eq!(again, first);
    let stamp2 = std::fs::metadata(first.join("meta.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(stamp, stamp2, "the cached scene was regenerated");
    // Only the stale folder and the scene: this run's temporary folder is gone.
    let entries: Vec<String> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(entries.len(), 2, "{entries:?}");
    // A different description gets a different folder.
    let mut other = desc.clone();
    other.seed = 3;
    assert_ne!(sim::cache_key(&other), sim::cache_key(&desc));
    // An incomplete folder under the final name (no meta.json) is never returned as a scene.
    let mut broken = desc.clone();
    broken.seed = 4;
    let half = cache.join(sim::cache_key(&broken));
    std::fs::create_dir_all(half.join("image")).unwrap();
    let err = sim::ensure_scene(&broken, &cache).unwrap_err();
    assert!(matches!(err, sim::SimError::OutputExists(_)), "{err}");
    // Unknown built-in names are errors that list the catalog.
    let err = sim::ensure_builtin("teapot", &cache)
        .unwrap_err()
        .to_string();
    assert!(err.contains("teapot") && err.contains("relief"), "{err}");
}
