//! Bad input is a clear error that names the key, file or value at fault: unknown effects and
//! keys, malformed TOML, meshes without faces or with NaN vertices, an empty resolution, and
//! inconsistent effects; through the library and through `neus-aug synth`.

use neus_aug::sim::{SceneDescription, SimError, SimScene};
use std::path::Path;
use std::process::Command;

fn parse(text: &str) -> Result<SceneDescription, SimError> {
    SceneDescription::from_toml_str(text, "test.toml", None)
}

fn err(text: &str) -> String {
    parse(text).expect_err("must be rejected").to_string()
}

const BLOB: &str = "[object]\nshape = \"blob\"\n";

#[test]
fn a_minimal_description_parses() {
    let d = parse(BLOB).unwrap();
    assert_eq!(d.rig.views, 49);
    assert_eq!(d.rig.resolution, [400, 300]);
    assert!(d.effects.shading.is_none());
}

#[test]
fn printed_descriptions_parse_back() {
    let out = Command::new(env!("CARGO_BIN_EXE_neus-aug"))
        .args([
            "synth",
            "blocks",
            "--print-toml",
            "--views",
            "7",
            "--degrade",
            "poisson:10",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let d = parse(&text).unwrap();
    let mut expected = neus_aug::sim::builtin("blocks").unwrap();
    expected.rig.views = 7;
    expected.effects.degrade = vec!["poisson:10".into()];
    assert_eq!(d, expected);
    assert!(text.contains("[effects.ground_plane]"), "{text}");
}

#[test]
fn unknown_effects_and_keys_are_named() {
    let e = err(&format!("{BLOB}[effects]\nshadow = {{}}\n"));
    assert!(
        e.contains("test.toml") && e.contains("unknown field `shadow`"),
        "{e}"
    );
    assert!(e.contains("shadows"), "the accepted names are listed: {e}");
    let e = err(&format!(
        "{BLOB}[effects]\nspecular = {{ strenght = 0.5 }}\n"
    ));
    assert!(e.contains("unknown field `strenght`"), "{e}");
    let e = err(&format!("{BLOB}[rig]\nview = 3\n"));
    assert!(e.contains("unknown field `view`"), "{e}");
    let e = err("[object]\nshape = \"teapot\"\n");
    assert!(e.contains("teapot") && e.contains("blob"), "{e}");
    let e = err(&format!(
        "{BLOB}[effects]\ntexture = {{ pattern = \"stripes\" }}\n"
    ));
    assert!(e.contains("stripes") && e.contains("multiscale"), "{e}");
    let e = err(&format!(
        "{BLOB}[effects]\ndegrade = [\"gaussian:0.1\", \"blur:3\"]\n"
    ));
    assert!(
        e.contains("effects.degrade[1]") && e.contains("blur:3"),
        "{e}"
    );
    let e = err(&format!("{BLOB}[effects]\ndegrade = [\"gaussian:-1\"]\n"));
    assert!(e.contains("effects.degrade[0]"), "{e}");
}

#[test]
fn malformed_toml_names_the_line() {
    let e = err("name = \"unterminated\n[object]\nshape = \"blob\"\n");
    assert!(e.contains("test.toml") && e.contains("line 1"), "{e}");
    let e = err(&format!("{BLOB}[rig]\nviews = \"many\"\n"));
    assert!(e.contains("line 4") && e.contains("views"), "{e}");
}

#[test]
fn out_of_range_values_name_their_key() {
    let cases: [(&str, &str); 10] = [
        ("[rig]\nresolution = [0, 300]\n", "rig.resolution"),
        ("[rig]\nresolution = [400, 0]\n", "rig.resolution"),
        ("[rig]\nviews = 0\n", "rig.views"),
        ("[render]\nspp = 0\n", "render.spp"),
        ("[gt]\nspacing_mm = -1.0\n", "gt.spacing_mm"),
        ("[gt]\nspacing_mm = 0.0001\n", "gt.spacing_mm"),
        ("[rig]\nelevation_deg = [60.0, 20.0]\n", "rig.elevation_deg"),
        ("[effects]\nspecular = {}\n", "effects.specular"),
        (
            "[effects.shading]\nmodel = \"lambert\"\ndirection = [0.0, 0.0, 0.0]\n",
            "effects.shading.direction",
        ),
        (
            "[effects.exposure]\nsigma = nan\n",
            "effects.exposure.sigma",
        ),
    ];
    for (extra, key) in cases {
        let e = err(&format!("{BLOB}{extra}"));
        assert!(e.contains(&format!("'{key}'")), "{extra:?} -> {e}");
    }
    let e = err("[object]\nshape = \"blob\"\nmesh = \"a.ply\"\n");
    assert!(e.contains("both"), "{e}");
    let e = err("[rig]\nviews = 3\n");
    assert!(e.contains("'object'") && e.contains("shape"), "{e}");
    // Shadows need a light.
    let e = err(&format!("{BLOB}[effects]\nshadows = {{}}\n"));
    assert!(
        e.contains("effects.shadows") && e.contains("lambert"),
        "{e}"
    );
}

fn mesh_desc(path: &Path) -> SceneDescription {
    let mut d = SceneDescription::default();
    d.object.mesh = Some(path.into());
    d.rig.resolution = [16, 12];
    d.rig.views = 2;
    d
}

fn prepare_err(path: &Path) -> String {
    match SimScene::prepare(&mesh_desc(path)) {
        Ok(_) => panic!("{} must be rejected", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_meshes_are_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let no_faces = d.join("cloud.ply");
    std::fs::write(
        &no_faces,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
    )
    .unwrap();
    let e = prepare_err(&no_faces);
    assert!(e.contains("cloud.ply") && e.contains("no faces"), "{e}");

    let nan = d.join("nan.ply");
    std::fs::write(
        &nan,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    // ply-rs's ASCII reader refuses the token itself; still an error naming the file.
    let e = prepare_err(&nan);
    assert!(e.contains("nan.ply"), "{e}");
    let nan_bin = d.join("nan_binary.ply");
    dtu_eval::ply::write(
        &nan_bin,
        &[[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]],
        None,
        &[[0, 1, 2]],
        &[],
    )
    .unwrap();
    let e = prepare_err(&nan_bin);
    assert!(
        e.contains("nan_binary.ply") && e.contains("non-finite"),
        "{e}"
    );

    let nan_obj = d.join("nan.obj");
    std::fs::write(&nan_obj, "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = prepare_err(&nan_obj);
    assert!(e.contains("nan.obj") && e.contains("non-finite"), "{e}");

    let empty_obj = d.join("empty.obj");
    std::fs::write(&empty_obj, "# nothing\nv 0 0 0\n").unwrap();
    let e = prepare_err(&empty_obj);
    assert!(e.contains("empty.obj") && e.contains("no faces"), "{e}");

    let bad_index = d.join("index.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let e = prepare_err(&bad_index);
    assert!(e.contains("index.obj") && e.contains("line 3"), "{e}");

    let flat = d.join("point.obj");
    std::fs::write(&flat, "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n").unwrap();
    let e = prepare_err(&flat);
    assert!(e.contains("point.obj") && e.contains("zero extent"), "{e}");

    let missing = d.join("missing.ply");
    let e = prepare_err(&missing);
    assert!(e.contains("missing.ply"), "{e}");
    let stl = d.join("model.stl");
    std::fs::write(&stl, "solid x\n").unwrap();
    let e = prepare_err(&stl);
    assert!(e.contains("model.stl") && e.contains("extension"), "{e}");
}

fn synth(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_neus-aug"))
        .arg("synth")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_command_line_reports_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out_s = out.to_str().unwrap();
    let (ok, e) = synth(&["blob", "--out", out_s, "--resolution", "0x300"]);
    assert!(
        !ok && e.contains("0x300") && e.contains("at least 1"),
        "{e}"
    );
    let (ok, e) = synth(&["blob", "--out", out_s, "--resolution", "400by300"]);
    assert!(!ok && e.contains("WIDTHxHEIGHT"), "{e}");
    let (ok, e) = synth(&["teapot", "--out", out_s]);
    assert!(!ok && e.contains("teapot") && e.contains("blob"), "{e}");
    let toml = dir.path().join("bad.toml");
    std::fs::write(&toml, format!("{BLOB}[effects]\nshadow = {{}}\n")).unwrap();
    let (ok, e) = synth(&[toml.to_str().unwrap(), "--out", out_s]);
    assert!(!ok && e.contains("bad.toml") && e.contains("shadow"), "{e}");
    let (ok, e) = synth(&["blob", "--out", out_s, "--views", "0"]);
    assert!(!ok && e.contains("rig.views"), "{e}");
    let (ok, e) = synth(&[
        "--mesh",
        dir.path().join("nope.ply").to_str().unwrap(),
        "--out",
        out_s,
    ]);
    assert!(!ok && e.contains("nope.ply"), "{e}");
    // Nothing was left behind by the failed runs.
    assert!(!out.exists());
    // A non-empty output folder is refused, and left untouched.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "x").unwrap();
    let (ok, e) = synth(&[
        "blob",
        "--out",
        out_s,
        "--views",
        "1",
        "--resolution",
        "8x6",
    ]);
    assert!(!ok && e.contains("not empty"), "{e}");
    assert_eq!(std::fs::read_to_string(out.join("keep.txt")).unwrap(), "x");
}
