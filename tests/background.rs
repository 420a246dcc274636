//! Training without masks with the learned background on a tiny `blob` with the
//! simulator's ground plane (a checker table in the images, never in the masks): the library
//! loop trains to finite losses and the background colour at the table's pixels outside the box
//! moves towards the table's colour; `reconstruct` with `data.masks=false` and the background
//! trains, extracts a mesh and scores it.

mod common;

use neus_aug::augment::{AugSampler, AugmentConfig};
use neus_aug::render::rays::ray_aabb;
use neus_aug::render::{BackgroundConfig, BackgroundKind, ModelConfig, NeusModel, RayBatch};
use neus_aug::scene::{Scene, View};
use neus_aug::sim;
use neus_aug::sim::desc::GroundPlane;
use neus_aug::train::data::camera_rays;
use neus_aug::train::{TrainConfig, TrainData, Trainer};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// 8 views at 48×36 of `blob` on the ground plane, generated once per test process.
fn scene() -> &'static Path {
    static SCENE: OnceLock<PathBuf> = OnceLock::new();
    SCENE.get_or_init(|| {
        let mut desc = sim::builtin("blob").unwrap();
        desc.effects.ground_plane = Some(GroundPlane::default());
        desc.rig.views = 8;
        desc.rig.resolution = [48, 36];
        desc.render.spp = 1;
        desc.gt.spacing_mm = 1.0;
        desc.gt.obs_res_mm = 4.0;
        let dir = tempfile::tempdir().unwrap().keep().join("blob-plane");
        sim::generate(&desc, &dir, &Default::default()).unwrap();
        dir
    })
}

/// A small background: 16 samples, 4 frequencies, width-32 networks.
fn background() -> BackgroundConfig {
    BackgroundConfig {
        kind: BackgroundKind::Nerfpp,
        n_outside: 16,
        n_frequencies: 4,
        n_neurons: 32,
        n_hidden_layers: 1,
        color_hidden_layers: 1,
        feature_dim: 7,
    }
}

/// Origins and directions (normalised space) and target colours of some pixels, `[n][3]` each.
type PixelRays = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 3]>);

/// The pixels of `view` whose ray misses the marched box (only the background can explain them)
/// and whose colour is not the simulator's empty-space colour (so they see the table): their
/// rays and target colours.
fn table_pixels(view: &View, empty: [f32; 3]) -> PixelRays {
    let (origins, dirs) = camera_rays(&view.camera);
    let (mut o, mut d, mut c) = (Vec::new(), Vec::new(), Vec::new());
    let w = view.camera.width as usize;
    for (i, (og, dg)) in origins.iter().zip(&dirs).enumerate() {
        let px = view.image.get(i % w, i / w);
        let differs = px.iter().zip(empty).any(|(a, b)| (a - b).abs() > 0.05);
        if ray_aabb(*og, *dg, 1.0).is_none() && differs {
            o.push(*og);
            d.push(*dg);
            c.push(px);
        }
    }
    (o, d, c)
}

fn mean_abs_error(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |k| (x[k] - y[k]).abs() as f64))
        .sum();
    s / (3 * a.len()) as f64
}

#[test]
fn background_learns_the_table_without_masks() {
    let scene = Scene::load(scene(), &Default::default()).unwrap();
    let desc_bg = sim::builtin("blob").unwrap().render.background;
    let mut cfg = ModelConfig::default();
    {
        let h = &mut cfg.field.hash_grid;
        h.n_levels = 6;
        h.log2_hashmap_size = 12;
        h.base_resolution = 8.0;
        h.per_level_scale = 1.5;
        let r = &mut cfg.render;
        r.num_samples_per_ray = 64;
        r.train_num_rays = 256;
        r.max_train_num_rays = 256;
        r.occupancy.resolution = 16;
        r.cos_anneal_end = 200;
        r.shards = 2;
    }
    cfg.background = background();
    let model = NeusModel::new(cfg).unwrap();
    let images = scene.views.iter().map(|v| v.image.clone()).collect();
    let cameras: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
    let sampler = AugSampler::new(images, &AugmentConfig::default()).unwrap();
    // No masks: the table is in the targets and nothing marks it as background.
    let data = TrainData::new(&cameras, sampler, None, model.config.render.background).unwrap();
    let train = TrainConfig::default();
    let mut trainer = Trainer::new(&model, &data, &train, 0, 0);
    let mut state = trainer.initial_state();

    let (mut o, mut d, mut target) = (Vec::new(), Vec::new(), Vec::new());
    for v in &scene.views {
        let (vo, vd, vc) = table_pixels(v, desc_bg);
        o.extend(vo);
        d.extend(vd);
        target.extend(vc);
    }
    assert!(
        o.len() > 100,
        "only {} table pixels outside the box",
        o.len()
    );
    let rays = RayBatch {
        origins: &o,
        dirs: &d,
        codes: &[],
        p: &[],
    };
    let before = mean_abs_error(
        &model.render_background(&state.params, &rays).unwrap(),
        &target,
    );

    let mut losses = Vec::new();
    for _ in 0..300 {
        let rep = trainer.step(&mut state).unwrap();
        assert!(rep.skipped.is_none(), "{rep:?}");
        assert!(
            rep.out.total.is_finite() && rep.out.rgb_l1.is_finite(),
            "{rep:?}"
        );
        assert_eq!(
            rep.out.n_valid_rays, rep.out.n_rays,
            "every ray has background samples"
        );
        losses.push(rep.out.rgb_l1);
    }
    assert!(state.params.iter().all(|v| v.is_finite()));
    let after_bg = model.render_background(&state.params, &rays).unwrap();
    let after = mean_abs_error(&after_bg, &target);
    // Those rays never enter the box, so the full render is the background's colour.
    let full = model
        .render(
            &state.params,
            &rays,
            model.config.inference_schedule(300),
            None,
        )
        .unwrap();
    assert_eq!(full.rgb, after_bg);
    let first: f64 = losses[..10].iter().sum::<f64>() / 10.0;
    let last: f64 = losses[losses.len() - 10..].iter().sum::<f64>() / 10.0;
    eprintln!(
        "table pixels {}: |C_bg − target| {before:.4} → {after:.4}; L1 {first:.4} → {last:.4}",
        o.len()
    );
    assert!(last < first, "L1 {first} → {last}");
    assert!(
        after < 0.6 * before,
        "background colour at the table: error {before} → {after}"
    );
}

#[test]
fn reconstruct_without_masks_with_the_background() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = common::tiny::write_config(tmp.path(), 24, "");
    let out = tmp.path().join("womask");
    let o = common::tiny::neus_aug()
        .arg("reconstruct")
        .arg(scene())
        .args(["--config", cfg.to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "--quiet"])
        .args([
            "--set",
            "data.masks=false",
            "--set",
            "model.background.kind=nerfpp",
            "--set",
            "model.background.n_outside=8",
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "reconstruct failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert!(
        m["train"]["final_loss"].as_f64().unwrap().is_finite(),
        "{m}"
    );
    assert!(
        m["chamfer"]["chamfer_sum"].as_f64().unwrap().is_finite(),
        "{m}"
    );
    assert!(m["psnr_heldout"].as_f64().unwrap().is_finite(), "{m}");
    // Without masks the tiny config's `auto` start falls back to the sphere init.
    assert!(m["train"]["hull_init"].is_null(), "{m}");
    assert!(out.join("mesh.ply").is_file());
    // The resolved config records the background; the checkpoint holds its two groups.
    let resolved = std::fs::read_to_string(out.join("config.toml")).unwrap();
    assert!(
        resolved.contains("[model.background]") && resolved.contains("nerfpp"),
        "{resolved}"
    );
    let ck = std::fs::read(out.join("checkpoint.safetensors")).unwrap();
    let ck = safetensors::SafeTensors::deserialize(&ck).unwrap();
    let names = ck.names();
    for g in ["params.bg_density", "params.bg_color"] {
        assert!(names.contains(&g), "{g} missing from {names:?}");
    }
}
