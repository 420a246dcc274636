//! User meshes (`--mesh FILE.ply|.obj`) are rendered the same way as built-in shapes: scaled into
//! the rig (bounding sphere of `object.radius_mm`), turned so their up axis is up, with ground
//! truth; closed meshes are recognised, open ones still work.

use neus_aug::sim::desc::UpAxis;
use neus_aug::sim::shapes::icosphere;
use neus_aug::sim::{builtin, SimScene};
use std::process::Command;

/// An ellipsoid 3× longer along the file's y axis than across, as (vertices, faces).
fn tall_ellipsoid() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let m = icosphere(3);
    let v = m
        .vertices
        .iter()
        .map(|p| [p[0] as f32 * 10.0, p[1] as f32 * 30.0, p[2] as f32 * 10.0])
        .collect();
    (v, m.faces)
}

fn extent_along(scene: &SimScene, dir: [f64; 3]) -> f64 {
    let d: Vec<f64> = scene
        .mesh_world
        .vertices
        .iter()
        .map(|v| (0..3).map(|k| v[k] as f64 * dir[k]).sum())
        .collect();
    d.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - d.iter().cloned().fold(f64::INFINITY, f64::min)
}

#[test]
fn a_ply_mesh_is_scaled_into_the_rig_and_its_up_axis_honoured() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tall.ply");
    let (v, f) = tall_ellipsoid();
    dtu_eval::ply::write(&path, &v, None, &f, &[]).unwrap();
    let mut desc = builtin("blob").unwrap();
    desc.object.shape = None;
    desc.object.mesh = Some(path.clone());
    desc.rig.resolution = [40, 30];
    desc.rig.views = 3;
    desc.gt.spacing_mm = 2.0;
    for (up, tall_is_up) in [(UpAxis::PosY, true), (UpAxis::PosZ, false)] {
        desc.object.up_axis = up;
        let scene = SimScene::prepare(&desc).unwrap();
        assert!(scene.closed_oriented, "a closed icosphere is recognised");
        // Bounding sphere radius is object.radius_mm (100 mm) about the bounding-box centre.
        let (lo, hi) = dtu_eval::mesh::bounds(&scene.mesh_world.vertices).unwrap();
        let c: Vec<f64> = (0..3).map(|k| 0.5 * (lo[k] + hi[k]) as f64).collect();
        let r = scene
            .mesh_world
            .vertices
            .iter()
            .map(|v| {
                (0..3)
                    .map(|k| (v[k] as f64 - c[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        assert!((r - 100.0).abs() < 1e-3, "bounding radius {r}");
        // World up is −y (see rig.rs): the long axis is vertical only with up_axis = +y.
        let vertical = extent_along(&scene, [0.0, -1.0, 0.0]);
        assert_eq!(
            vertical > 150.0,
            tall_is_up,
            "{up:?}: vertical extent {vertical}"
        );
        let gt = scene.ground_truth();
        assert!(gt.points.len() > 1000);
        let v0 = scene.render_view(0);
        assert!(v0.mask.coverage() > 0.02);
    }
}

#[test]
fn the_command_line_renders_obj_meshes_open_or_closed() {
    let dir = tempfile::tempdir().unwrap();
    let (v, f) = tall_ellipsoid();
    let mut obj = String::new();
    for p in &v {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    // Drop one face: the mesh is open.
    for t in &f[1..] {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let path = dir.path().join("open.obj");
    std::fs::write(&path, obj).unwrap();
    let out = dir.path().join("scene");
    let status = Command::new(env!("CARGO_BIN_EXE_neus-aug"))
        .args(["synth", "--mesh", path.to_str().unwrap(), "--up-axis", "+y"])
        .args([
            "--resolution",
            "40x30",
            "--views",
            "4",
            "--gt-spacing",
            "2",
            "--quiet",
        ])
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["name"], "open");
    assert_eq!(meta["scan"], 100);
    assert_eq!(meta["mesh_closed_oriented"], false);
    assert!(meta["gt"]["points"].as_u64().unwrap() > 1000);
    assert!(out.join("Points/stl/stl100_total.ply").is_file());
    assert!(out.join("ObsMask/ObsMask100_10.mat").is_file());
    let scene = neus_aug::scene::Scene::load(&out, &Default::default()).unwrap();
    assert_eq!(scene.views.len(), 4);
}
