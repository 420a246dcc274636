//! Inputs of the user-facing surfaces that must be refused, with the file, entry or option
//! named and what is wrong with it: `import colmap|transforms`, `synth --mesh` and `--out`.
//! Each test is one case; where a command fails, what was there before is left as it was.
//! Scenes are the tiny scene of `tests/common/tiny.rs`, exported with the library's exporters.

mod common;

use common::tiny::{neus_aug, scene as tiny_scene};
use nalgebra::Vector3;
use neus_aug::import::{colmap, export};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "command failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Fails, without a panic, with every one of `expect` in the message; returns it.
fn refused(o: &Output, expect: &[&str]) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        !o.status.success(),
        "expected a failure for {expect:?}:\n{}",
        String::from_utf8_lossy(&o.stdout)
    );
    for e in expect {
        assert!(err.contains(e), "message lacks {e:?}:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// The tiny scene's COLMAP text model, exported into `dir/colmap/sparse/0`.
fn colmap_model(dir: &Path) -> PathBuf {
    export::export_colmap(tiny_scene(), &dir.join("colmap")).unwrap()
}

/// The tiny scene's transforms.json (absolute image paths), exported into `dir`.
fn transforms_json(dir: &Path) -> PathBuf {
    export::export_transforms(tiny_scene(), dir).unwrap()
}

/// `neus-aug import colmap MODEL --images <tiny scene>/image --out OUT EXTRA...`.
fn import_colmap(model: &Path, out: &Path, extra: &[&str]) -> Output {
    neus_aug()
        .args(["import", "colmap"])
        .arg(model)
        .arg("--images")
        .arg(tiny_scene().join("image"))
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// `neus-aug import transforms JSON --out OUT EXTRA...`.
fn import_transforms(json: &Path, out: &Path, extra: &[&str]) -> Output {
    neus_aug()
        .args(["import", "transforms"])
        .arg(json)
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn edit_json(path: &Path, f: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

// --------------------------------------------- BAD 1: a region no camera sees; no baseline

#[test]
fn bad1_a_region_of_interest_no_camera_sees_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let model = colmap_model(tmp.path());
    let json = transforms_json(tmp.path());
    let far = ["--roi-center", "5000,5000,5000", "--roi-radius", "10"];
    let out = tmp.path().join("out");
    // (One camera of the tiny rig has that far point in its view: still short of two.)
    let err = refused(
        &import_colmap(&model, &out, &far),
        &["region of interest", "5000", "of 8 cameras", "two at least"],
    );
    assert!(err.contains("--roi-center"), "{err}");
    assert!(!out.exists(), "a refused import wrote {}", out.display());
    refused(
        &import_transforms(&json, &out, &far),
        &["region of interest", "of 8 cameras", "two at least"],
    );
    assert!(!out.exists());
    // Far behind every camera: against the mean viewing direction, from the mean centre.
    let cams = export::read_scene_cameras(tiny_scene()).unwrap().cameras;
    let n = cams.len() as f64;
    let centre = cams.iter().map(|c| c.center).sum::<Vector3<f64>>() / n;
    let axis = cams
        .iter()
        .map(|c| c.r.row(2).transpose())
        .sum::<Vector3<f64>>()
        / n;
    let behind = centre - 1e4 * axis.normalize();
    let behind = format!("{},{},{}", behind.x, behind.y, behind.z);
    let roi = ["--roi-center", behind.as_str(), "--roi-radius", "10"];
    refused(
        &import_colmap(&model, &out, &roi),
        &["seen by 0 of 8 cameras"],
    );
    assert!(!out.exists());
    // The region the importer picks itself is seen by every camera.
    ok(&import_colmap(&model, &out, &[]));
}

#[test]
fn bad1_cameras_that_all_share_one_centre_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let model_dir = colmap_model(tmp.path());
    // Every image keeps its rotation but moves to the first image's centre: a panorama turned on
    // a tripod, with no baseline to triangulate from.
    let (mut model, _) = colmap::read_model(&model_dir).unwrap();
    let r0 = colmap::rotation(model.images[0].qvec).unwrap();
    let c0 = -(r0.transpose() * Vector3::from(model.images[0].tvec));
    for im in &mut model.images {
        let t = -(colmap::rotation(im.qvec).unwrap() * c0);
        im.tvec = [t.x, t.y, t.z];
    }
    let pano = tmp.path().join("pano");
    colmap::write_text(&model, &pano).unwrap();
    let out = tmp.path().join("out");
    let roi = ["--roi-center", "0,0,0", "--roi-radius", "1"];
    for extra in [&[][..], &roi[..]] {
        refused(
            &import_colmap(&pano, &out, extra),
            &["all 8 cameras share one centre", "no baseline"],
        );
        assert!(!out.exists());
    }
    let json = transforms_json(tmp.path());
    edit_json(&json, |v| {
        let frames = v["frames"].as_array_mut().unwrap();
        let c0: Vec<Value> = (0..3)
            .map(|r| frames[0]["transform_matrix"][r][3].clone())
            .collect();
        for f in frames.iter_mut() {
            for (r, c) in c0.iter().enumerate() {
                f["transform_matrix"][r][3] = c.clone();
            }
        }
    });
    refused(
        &import_transforms(&json, &out, &[]),
        &["all 8 cameras share one centre", "no baseline"],
    );
    assert!(!out.exists());
}

// ----------------------------------------------- BAD 2: one photograph named by two entries

#[test]
fn bad2_an_image_named_twice_is_refused_naming_both_entries() {
    let tmp = tempfile::tempdir().unwrap();
    let model_dir = colmap_model(tmp.path());
    let (mut model, _) = colmap::read_model(&model_dir).unwrap();
    let (first, dup) = (model.images[0].clone(), model.images[2].id);
    model.images[2].name = first.name.clone();
    let text = tmp.path().join("text");
    let bin = tmp.path().join("bin");
    colmap::write_text(&model, &text).unwrap();
    colmap::write_binary(&model, &bin).unwrap();
    let out = tmp.path().join("out");
    for (dir, file) in [(&text, "images.txt"), (&bin, "images.bin")] {
        refused(
            &import_colmap(dir, &out, &[]),
            &[
                file,
                &format!("image {}", first.id),
                &format!("image {dup}"),
                &first.name,
            ],
        );
        assert!(!out.exists());
    }
    // transforms.json: frame 3 names frame 1's file, once without its extension.
    let json = transforms_json(tmp.path());
    edit_json(&json, |v| {
        let frames = v["frames"].as_array_mut().unwrap();
        let p = frames[1]["file_path"].as_str().unwrap().to_string();
        frames[3]["file_path"] = Value::String(p.trim_end_matches(".png").into());
    });
    refused(
        &import_transforms(&json, &out, &[]),
        &["frame 1", "frame 3", "000001.png"],
    );
    assert!(!out.exists());
}

// ------------------------------------- WEAK: a failed import removes what it created, only

/// The tiny scene's images with view 5's PNG cut short (its header still reads).
fn images_with_a_truncated_png(dir: &Path) -> PathBuf {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for e in std::fs::read_dir(tiny_scene().join("image")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, images.join(p.file_name().unwrap())).unwrap();
    }
    let victim = images.join("000005.png");
    let bytes = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, &bytes[..bytes.len() / 2]).unwrap();
    images
}

#[test]
fn weak_a_failed_import_removes_what_it_created_and_nothing_else() {
    let tmp = tempfile::tempdir().unwrap();
    let model = colmap_model(tmp.path());
    let images = images_with_a_truncated_png(tmp.path());
    let run = |out: &Path| {
        neus_aug()
            .args(["import", "colmap"])
            .arg(&model)
            .arg("--images")
            .arg(&images)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    // Absent, below folders that do not exist yet: all of them go.
    let new = tmp.path().join("new/deeper/scene");
    refused(&run(&new), &["000005.png"]);
    assert!(
        !tmp.path().join("new").exists(),
        "created folders were left"
    );
    // An empty folder the user made: it stays, empty.
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    refused(&run(&empty), &["000005.png"]);
    assert!(empty.is_dir(), "the user's folder was removed");
    assert_eq!(std::fs::read_dir(&empty).unwrap().count(), 0, "leftovers");
    // So a retry with the images fixed is not refused as "not empty".
    ok(&import_colmap(&model, &empty, &[]));
    assert!(empty.join("cameras_sphere.npz").is_file());
}

// ------------------------------------------------------ WEAK: an absent --masks folder

#[test]
fn weak_an_absent_mask_folder_is_named_as_a_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let model = colmap_model(tmp.path());
    let out = tmp.path().join("out");
    let nowhere = tmp.path().join("no-masks");
    let err = refused(
        &import_colmap(&model, &out, &["--masks", nowhere.to_str().unwrap()]),
        &["--masks", "no-masks", "does not exist"],
    );
    assert!(!err.contains(".png"), "{err}");
    // A folder without the mask of one image: the names tried are listed, each once.
    let masks = tmp.path().join("masks");
    std::fs::create_dir(&masks).unwrap();
    for e in std::fs::read_dir(tiny_scene().join("mask")).unwrap() {
        let p = e.unwrap().path();
        if !p.ends_with("003.png") {
            std::fs::copy(&p, masks.join(p.file_name().unwrap())).unwrap();
        }
    }
    let err = refused(
        &import_colmap(&model, &out, &["--masks", masks.to_str().unwrap()]),
        &[
            "no mask for image '000003.png'",
            "000003.png.png",
            "numbered 3",
        ],
    );
    assert!(!err.contains("is missing"), "{err}");
    assert!(!out.exists());
}

// ---------------------------------------------- WEAK: a lens model that folds back

#[test]
fn weak_a_radial_distortion_that_folds_inside_the_image_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let model_dir = colmap_model(tmp.path());
    let out = tmp.path().join("out");
    // SIMPLE_RADIAL f cx cy k: r(1 + k r²) turns back at r = 1/sqrt(-3k), far inside the image
    // for k = -50; k = -0.05 stays monotonic over it and imports.
    for (k, refuse) in [(-50.0, true), (-0.05, false)] {
        let (mut model, _) = colmap::read_model(&model_dir).unwrap();
        for cam in model.cameras.values_mut() {
            let p = cam.params.clone();
            cam.model = "SIMPLE_RADIAL".into();
            cam.params = vec![p[0], p[2], p[3], k];
        }
        let dir = tmp.path().join(format!("k{k}"));
        colmap::write_text(&model, &dir).unwrap();
        let o = import_colmap(&dir, &out, &[]);
        if refuse {
            refused(
                &o,
                &["cameras.txt", "camera 1", "SIMPLE_RADIAL", "folds back"],
            );
            assert!(!out.exists());
        } else {
            ok(&o);
        }
    }
}

// ---------------------------------------------- WEAK: --out a dangling symbolic link

#[test]
fn weak_out_as_a_dangling_symlink_is_named_and_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let model = colmap_model(tmp.path());
    let target = tmp.path().join("gone");
    let link = tmp.path().join("link");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let expect = ["link", "symbolic link", "gone", "does not exist"];
    let err = refused(&import_colmap(&model, &link, &[]), &expect);
    assert!(!err.contains("os error"), "{err}");
    let err = refused(
        &neus_aug()
            .args(["synth", "blob", "--views", "2", "--resolution", "16x12"])
            .args(["--quiet", "--out"])
            .arg(&link)
            .output()
            .unwrap(),
        &expect,
    );
    assert!(!err.contains("os error"), "{err}");
    assert_eq!(std::fs::read_link(&link).unwrap(), target);
    assert!(!target.exists());
}

// ----------------------------------------------- WEAK: synth --mesh with an unusable mesh

fn synth_mesh(mesh: &Path, out: &Path) -> Output {
    neus_aug()
        .arg("synth")
        .arg("--mesh")
        .arg(mesh)
        .args(["--views", "3", "--resolution", "32x24", "--quiet", "--out"])
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn weak_synth_refuses_a_mesh_without_area_or_with_a_vertex_far_off() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let write = |name: &str, text: &str| {
        let p = tmp.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    // Collinear and repeated corners only: nothing to render.
    let flat = write(
        "flat.obj",
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 2\n",
    );
    refused(&synth_mesh(&flat, &out), &["flat.obj", "zero surface area"]);
    assert!(!out.exists());
    // One vertex at 1e30 (on a sliver face): scaled into the rig, the rest shrinks to nothing.
    let far = write("far.obj", &format!("{tetra}v 1e30 0 0\nf 1 2 5\n"));
    refused(
        &synth_mesh(&far, &out),
        &["far.obj", "vertex 4", "1e30", "less than one pixel"],
    );
    assert!(!out.exists());
    // The same tetrahedron without it renders.
    let fine = write("fine.obj", tetra);
    ok(&synth_mesh(&fine, &out));
}

#[test]
fn weak_synth_names_a_mesh_file_that_is_not_text() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let garbage = tmp.path().join("garbage.obj");
    let bytes: Vec<u8> = (0..2000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&garbage, &bytes).unwrap();
    let err = refused(&synth_mesh(&garbage, &out), &["garbage.obj", "not a text"]);
    assert!(!err.contains("cannot access"), "{err}");
    assert!(!out.exists());
}
