//! `neus-aug export` and `reconstruct`'s export step end to end on tiny synthetic scenes: the
//! round trip (the textured and vertex-coloured meshes rendered at the held-out cameras against
//! the network's own render), the files other tools open (`scripts/crosscheck_export.py`:
//! trimesh and Open3D), the geometry of `mesh.ply` unchanged, the turntable, and a clear error
//! with nothing written for each kind of bad input.

mod common;

use common::tiny::neus_aug;
use neus_aug::sim;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::OnceLock;

/// A tiny scene of the built-in `name`: 12 views at 64×48.
fn tiny_scene(name: &str) -> PathBuf {
    let mut desc = sim::builtin(name).unwrap();
    desc.rig.views = 12;
    desc.rig.resolution = [64, 48];
    desc.render.spp = 1;
    desc.gt.spacing_mm = 1.0;
    desc.gt.obs_res_mm = 4.0;
    let root = tempfile::tempdir().unwrap().keep();
    let dir = root.join(name);
    sim::generate(&desc, &dir, &Default::default()).unwrap();
    dir
}

/// The tiny configuration at 300 steps, a 64³ refined mesh, held-out renders at full size, the
/// textured export on at 256², and a small turntable.
fn config(dir: &Path) -> PathBuf {
    let extra = "[export]\ntextured = true\ntexture_size = 256\nturntable_frames = 8\n\
                 turntable_size = [40, 30]\n";
    let p = common::tiny::write_config(dir, 300, extra);
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("fine_res = 32", "fine_res = 64")
        .replace("render_downscale = 2", "render_downscale = 1")
        .replace("holdout = 1", "holdout = 2");
    std::fs::write(&p, text).unwrap();
    p
}

fn ok(o: &Output) -> String {
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "command failed:\n{text}");
    text
}

/// One trained run per scene, shared by the tests of this process.
fn run(name: &'static str) -> &'static Path {
    static BLOB: OnceLock<PathBuf> = OnceLock::new();
    static RELIEF: OnceLock<PathBuf> = OnceLock::new();
    let cell = if name == "blob" { &BLOB } else { &RELIEF };
    cell.get_or_init(|| {
        let scene = tiny_scene(name);
        let tmp = tempfile::tempdir().unwrap().keep();
        let cfg = config(&tmp);
        let out = tmp.join("run");
        ok(&neus_aug()
            .arg("reconstruct")
            .arg(&scene)
            .args(["--config", cfg.to_str().unwrap(), "--out"])
            .arg(&out)
            .arg("--quiet")
            .output()
            .unwrap());
        out
    })
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// `export RUN --check`: the textured mesh within 2 dB of the network's held-out PSNR, the
/// vertex-coloured one within 4 dB, no fallbacks, and the files open in trimesh and Open3D.
fn round_trip(name: &'static str) {
    let run = run(name);
    let out = run.join("export");
    let text = ok(&neus_aug()
        .args([
            "export",
            run.to_str().unwrap(),
            "--check",
            "--texture-size",
            "256",
        ])
        .output()
        .unwrap());
    let s = json(&out.join("export.json"));
    let c = &s["check"];
    let gap = |k: &str| c[k].as_f64().unwrap_or_else(|| panic!("{k}: {s}"));
    eprintln!(
        "{name}: network {:.2} dB, textured {:.2}, vertex colours {:.2}, along the rays {:.2}\n{text}",
        gap("network"),
        gap("textured"),
        gap("vertex_colors"),
        gap("along_rays")
    );
    assert!(gap("network") > 15.0, "the tiny run trained: {s}");
    assert!(gap("textured_gap") <= 2.0, "textured mesh: {s}");
    assert!(gap("vertex_gap") <= 4.0, "vertex-coloured mesh: {s}");
    assert_eq!(s["color_fallbacks"], 0, "{s}");
    assert_eq!(s["texture"]["fallbacks"], 0, "{s}");
    for f in [
        "mesh.ply",
        "mesh_textured.obj",
        "mesh_textured.mtl",
        "mesh_textured.png",
        "mesh_textured.glb",
        "turntable.gif",
    ] {
        assert!(out.join(f).is_file(), "{f} missing: {s}");
    }
    // The run's own mesh.ply and the export's hold the same geometry and the same colours.
    assert_eq!(
        std::fs::read(run.join("mesh.ply")).unwrap(),
        std::fs::read(out.join("mesh.ply")).unwrap()
    );
    crosscheck(&out);
}

#[test]
fn blob_round_trip_and_crosscheck() {
    round_trip("blob");
}

#[test]
fn relief_round_trip_and_crosscheck() {
    round_trip("relief");
}

/// `scripts/crosscheck_export.py DIR`: trimesh and Open3D load the PLY (normals, non-constant
/// colours), the OBJ (UVs in [0, 1], the texture found) and the GLB (texture, metres).
fn crosscheck(dir: &Path) {
    let python = std::process::Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !python {
        eprintln!("SKIPPED: python3 is not installed, the trimesh/Open3D cross-check cannot run");
        return;
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/crosscheck_export.py");
    let text = ok(&std::process::Command::new("python3")
        .arg(script)
        .arg(dir)
        .output()
        .unwrap());
    assert!(text.contains("OK: trimesh and open3d read"), "{text}");
}

/// `reconstruct`'s own outputs: `mesh.ply` has colours and normals and the very geometry of the
/// geometry-only file (`export.colors = false` writes that file byte for byte as before), the
/// turntable has its frames, the held-out sheet its rows, the textured files are there.
#[test]
fn reconstruct_writes_colours_turntable_and_sheet_with_the_same_geometry() {
    let a = run("blob");
    let m = json(&a.join("metrics.json"));
    let total = m["timings_s"]["total"].as_f64().unwrap();
    let export = m["timings_s"]["export"].as_f64().unwrap();
    assert!(export > 0.0 && export < total, "{m}");
    let colored = std::fs::read(a.join("mesh.ply")).unwrap();
    let header = String::from_utf8_lossy(&colored[..400]).into_owned();
    assert!(header.contains("property float nx") && header.contains("property uchar red"));
    let mesh = dtu_eval::ply::read_mesh(&a.join("mesh.ply")).unwrap();
    assert!(!mesh.faces.is_empty());
    // The geometry-only file of the same mesh is what `export.colors = false` leaves.
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("g.ply");
    dtu_eval::ply::write_mesh(&g, &mesh).unwrap();
    assert_eq!(dtu_eval::ply::read_mesh(&g).unwrap(), mesh);
    // The turntable: 8 frames of 80×30, not all the same.
    let mut dec = gif::DecodeOptions::new();
    dec.set_color_output(gif::ColorOutput::RGBA);
    let mut d = dec
        .read_info(std::fs::File::open(a.join("renders/turntable.gif")).unwrap())
        .unwrap();
    assert_eq!((d.width(), d.height()), (80, 30));
    let mut frames = Vec::new();
    while let Some(f) = d.read_next_frame().unwrap() {
        frames.push(f.buffer.to_vec());
    }
    assert_eq!(frames.len(), 8);
    assert!(frames.windows(2).any(|w| w[0] != w[1]), "the object turns");
    let sheet = image::open(a.join("renders/heldout_sheet.png")).unwrap();
    assert_eq!(sheet.width(), 3 * 64 + 4, "truth, render, normals");
    assert_eq!(sheet.height(), 2 * 48 + 2, "two held-out views");
    for f in [
        "mesh_textured.obj",
        "mesh_textured.png",
        "mesh_textured.glb",
    ] {
        assert!(a.join(f).is_file(), "{f}");
    }
    // `export.colors = false`: the old geometry-only bytes (the rest unchanged).
    let b = tmp.path().join("plain");
    let scene = json(&a.join("metrics.json"))["scene"]["dir"]
        .as_str()
        .unwrap()
        .to_string();
    let cfg = config(tmp.path());
    ok(&neus_aug()
        .args([
            "reconstruct",
            &scene,
            "--config",
            cfg.to_str().unwrap(),
            "--out",
        ])
        .arg(&b)
        .args([
            "--quiet",
            "--set",
            "export.colors=false",
            "--set",
            "export.textured=false",
        ])
        .output()
        .unwrap());
    let plain = std::fs::read(b.join("mesh.ply")).unwrap();
    assert_eq!(plain, std::fs::read(&g).unwrap(), "geometry-only bytes");
    assert!(!b.join("mesh_textured.obj").exists());
}

/// Each bad input is refused with the file or option named, and nothing is written.
#[test]
fn bad_inputs_are_named_and_write_nothing() {
    let run = run("blob");
    let tmp = tempfile::tempdir().unwrap();
    let fails = |args: &[&str], expect: &[&str]| {
        let out = tmp.path().join("out");
        let o = neus_aug()
            .arg("export")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "{args:?} should fail");
        for e in expect {
            assert!(err.contains(e), "{args:?}: expected {e:?} in:\n{err}");
        }
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    };
    let r = run.to_str().unwrap();
    fails(
        &[r, "--texture-size", "0"],
        &["--texture-size", "16..=16384"],
    );
    fails(
        &[r, "--texture-size", "20000"],
        &["--texture-size", "20000"],
    );
    fails(&[r, "--resolution", "1"], &["--resolution"]);
    // A folder without a checkpoint.
    let bare = tmp.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::copy(run.join("config.toml"), bare.join("config.toml")).unwrap();
    fails(&[bare.to_str().unwrap()], &["checkpoint.safetensors"]);
    // Not a run folder at all.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fails(&[empty.to_str().unwrap()], &["config.toml"]);
    // A checkpoint from another configuration.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    for f in ["checkpoint.safetensors", "mesh.ply", "metrics.json"] {
        std::fs::copy(run.join(f), other.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(run.join("config.toml")).unwrap();
    let changed = text.replacen("seed = 0", "seed = 5", 1);
    assert_ne!(text, changed);
    std::fs::write(other.join("config.toml"), changed).unwrap();
    fails(
        &[other.to_str().unwrap()],
        &["checkpoint.safetensors", "another configuration"],
    );
    // An empty mesh.
    let hollow = tmp.path().join("hollow");
    std::fs::create_dir_all(&hollow).unwrap();
    for f in ["checkpoint.safetensors", "config.toml", "metrics.json"] {
        std::fs::copy(run.join(f), hollow.join(f)).unwrap();
    }
    dtu_eval::ply::write_points(&hollow.join("mesh.ply"), &[[0.0; 3]], None).unwrap();
    fails(&[hollow.to_str().unwrap()], &["mesh.ply", "empty"]);
}
