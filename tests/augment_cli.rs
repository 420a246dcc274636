//! `neus-aug augment` end to end: `--apply` on PNG files, the contact sheet, clear errors on bad
//! input, and the Pillow / colorsys cross-check (scripts/crosscheck_augment.py).

mod common;

use neus_aug::augment::{ImageOp, Manipulation};
use neus_aug::scene::image::RgbImage;
use neus_aug::scene::{LoadOptions, Scene};
use rand::SeedableRng;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_neus-aug");

fn neus_aug(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("neus-aug binary runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small 8-bit-exact test image with gray pixels, saturated colours and texture.
fn write_test_image(dir: &Path) -> (PathBuf, RgbImage) {
    let img = RgbImage::from_fn(21, 14, |x, y| {
        let v = ((x * 37 + y * 91) % 256) as f32 / 255.0;
        match (x + y) % 4 {
            0 => [v, v, v],
            1 => [v, 1.0 - v, 0.2],
            2 => [1.0, 0.0, v],
            _ => [
                ((x * 13) % 256) as f32 / 255.0,
                v,
                ((y * 17) % 256) as f32 / 255.0,
            ],
        }
    });
    let path = dir.join("in.png");
    img.save(&path).unwrap();
    let loaded = RgbImage::load(&path).unwrap();
    (path, loaded)
}

#[test]
fn apply_writes_the_library_result_and_identity_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let (input, img) = write_test_image(dir.path());
    let out = dir.path().join("out.png");
    for spec in [
        "brightness:0",
        "contrast:0",
        "hue:0",
        "sharpness:0",
        "identity",
    ] {
        let o = neus_aug(&["augment", "--apply", spec, s(&input), s(&out)]);
        assert!(
            o.status.success(),
            "{spec}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(
            RgbImage::load(&out).unwrap(),
            img,
            "{spec} changed the image"
        );
    }
    for spec in [
        "hue:-0.3",
        "sharpness:0.8",
        "contrast:-0.5",
        "motion-blur:2.5",
    ] {
        let o = neus_aug(&["augment", "--apply", spec, s(&input), s(&out)]);
        assert!(
            o.status.success(),
            "{spec}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let op: ImageOp = spec.parse().unwrap();
        let expect_path = dir.path().join("expect.png");
        op.apply(&img, &mut rand_pcg::Pcg64Mcg::seed_from_u64(0))
            .save(&expect_path)
            .unwrap();
        let (got, expect) = (
            RgbImage::load(&out).unwrap(),
            RgbImage::load(&expect_path).unwrap(),
        );
        assert_eq!(got, expect, "{spec}");
        assert_ne!(got, img, "{spec} should change the image");
    }
}

#[test]
fn random_degradations_follow_the_seed() {
    let dir = tempfile::tempdir().unwrap();
    let (input, _) = write_test_image(dir.path());
    let run = |seed: &str, name: &str| {
        let out = dir.path().join(name);
        let o = neus_aug(&[
            "augment",
            "--apply",
            "gaussian:0.05",
            "--seed",
            seed,
            s(&input),
            s(&out),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).unwrap()
    };
    let (a, b, c) = (run("3", "a.png"), run("3", "b.png"), run("4", "c.png"));
    assert_eq!(a, b, "same seed, same bytes");
    assert_ne!(a, c, "another seed, other noise");
}

#[test]
fn contact_sheet_is_written_with_its_legend() {
    let dir = tempfile::tempdir().unwrap();
    let (input, img) = write_test_image(dir.path());
    let out = dir.path().join("sheet");
    let o = neus_aug(&["augment", s(&input), "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sheet = RgbImage::load(&out.join("contact_sheet.png")).unwrap();
    assert_eq!(
        (sheet.width, sheet.height),
        (6 * img.width + 7 * 4, 7 * img.height + 8 * 4)
    );
    let legend = std::fs::read_to_string(out.join("contact_sheet.txt")).unwrap();
    let cells: Vec<&str> = legend.lines().filter(|l| l.starts_with("row ")).collect();
    assert_eq!(cells.len(), 42, "{legend}");
    for m in Manipulation::NON_IDENTITY {
        assert!(
            legend.contains(&format!("{}:", m.name())),
            "{m} missing:\n{legend}"
        );
    }
    for kind in [
        "gaussian:0.1",
        "motion-blur:5",
        "poisson:10",
        "salt-pepper:0.05",
        "speckle:0.4",
    ] {
        assert!(legend.contains(kind), "{kind} missing:\n{legend}");
    }
    // --max-size shrinks the view first.
    let o = neus_aug(&["augment", s(&input), "--out", s(&out), "--max-size", "7"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sheet = RgbImage::load(&out.join("contact_sheet.png")).unwrap();
    assert_eq!(sheet.width, 6 * 7 + 7 * 4);
}

#[test]
fn contact_sheet_of_a_scene_folder_shows_the_chosen_view() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    common::write_random_scene(&scene_dir, 3, 5, 40, 30);
    let out = dir.path().join("sheet");
    let o = neus_aug(&["augment", s(&scene_dir), "--out", s(&out), "--view", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sheet = RgbImage::load(&out.join("contact_sheet.png")).unwrap();
    assert_eq!(
        (sheet.width, sheet.height),
        (6 * 40 + 7 * 4, 7 * 30 + 8 * 4)
    );
    // Row 0, column 2 is brightness at p = 0: view 1 itself.
    let scene = Scene::load(&scene_dir, &LoadOptions::default()).unwrap();
    let view = &scene.views[1].image;
    let (x0, y0) = (4 + 2 * (40 + 4), 4);
    for (x, y) in [(0, 0), (17, 9), (39, 29)] {
        assert_eq!(
            sheet.get(x0 + x, y0 + y),
            view.get(x, y),
            "pixel ({x}, {y})"
        );
    }
    let o = neus_aug(&["augment", s(&scene_dir), "--out", s(&out), "--view", "3"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("has 3 views"), "{err}");
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (input, _) = write_test_image(dir.path());
    let out = dir.path().join("out.png");
    let cases: &[(&[&str], &str)] = &[
        (
            &["--apply", "blur:0.3", s(&input), s(&out)],
            "unknown manipulation or degradation `blur`",
        ),
        (
            &["--apply", "hue:0.7", s(&input), s(&out)],
            "hue p = 0.7 is out of range: expected [-0.5, 0.5]",
        ),
        (
            &["--apply", "brightness:-1.5", s(&input), s(&out)],
            "brightness p = -1.5",
        ),
        (
            &["--apply", "poisson:0", s(&input), s(&out)],
            "poisson q = 0 is out of range",
        ),
        (
            &["--apply", "motion-blur:500", s(&input), s(&out)],
            "[1, 100]",
        ),
        (
            &["--apply", "salt-pepper:x", s(&input), s(&out)],
            "`x` is not a number",
        ),
        (
            &["--apply", "contrast", s(&input), s(&out)],
            "needs its intensity",
        ),
        (&["--apply", "contrast:0.2", s(&input)], "needs two paths"),
        (
            &["--apply", "contrast:0.2", "missing.png", s(&out)],
            "missing.png",
        ),
        (&[s(&input)], "--out DIR is required"),
        (&[s(dir.path()), "--out", s(&out)], "cannot load scene"),
        (
            &[s(&input), "--out", s(&out), "--view", "2"],
            "needs a scene folder",
        ),
    ];
    for (args, expect) in cases {
        let o = neus_aug(&[&["augment"], *args].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(
            err.contains(expect),
            "{args:?}: stderr does not mention `{expect}`:\n{err}"
        );
    }
    assert!(!out.exists(), "no output may be written on error");
}

/// Runs scripts/crosscheck_augment.py (Pillow ImageEnhance and colorsys); skipped, saying why,
/// only when python3 is absent.
#[test]
fn crosscheck_with_pillow_and_colorsys() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("SKIPPED crosscheck_augment.py: python3 is not installed");
        return;
    }
    let o = Command::new("python3")
        .arg(root.join("scripts/crosscheck_augment.py"))
        .arg(BIN)
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "cross-check failed:\n{stdout}\n{stderr}"
    );
    assert!(
        stdout.contains("all 90 manipulation cases agree"),
        "{stdout}"
    );
}
