//! Numerical hard cases of the model, each checked for finite values and the correct limit.
//! (Unit-level cases live beside the code: saturated sigmoids, SDF = 0 and cos = 0 in
//! `render::alpha`, all-ones alphas in `render::composite`, huge steps in `train::adam`.)

mod field_common;

use field_common::{batch, perturbed_params, seed, tiny_background_config, tiny_config};
use neus_aug::render::{NeusModel, OccupancyGrid, RayBatch};
use neus_aug::train::{AdamW, AdamWConfig, OptimError, Targets, TrainStep};

fn all_finite(xs: &[f32]) -> bool {
    xs.iter().all(|v| v.is_finite())
}

/// inv_s far above the 1e6 clip: finite loss and gradients, zero variance gradient (clipped),
/// the expected inv_s.
#[test]
fn inv_s_at_the_clip() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let mut p = perturbed_params(&model, seed());
    let var = model.layout.group("variance").unwrap().offset;
    p[var] = 3.0; // exp(30) ≫ 1e6
    let b = batch(16, 3);
    let rays = b.rays();
    let t = b.targets();
    let mut g = vec![0f32; p.len()];
    let o = model
        .train_step(&p, &mut g, &rays, &t, model.config.schedule(500), None, 1)
        .unwrap();
    assert_eq!(o.inv_s, 1e6);
    assert!(o.total.is_finite() && all_finite(&g), "{o:?}");
    assert_eq!(g[var], 0.0, "the clip blocks the variance gradient");
    let r = model
        .render(&p, &rays, model.config.inference_schedule(500), None)
        .unwrap();
    assert!(r
        .rgb
        .iter()
        .flatten()
        .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
}

/// Rays that miss the box and rays whose every interval is skipped: background colour, zero
/// opacity, excluded from the colour loss, finite everything.
#[test]
fn rays_without_samples() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let p = perturbed_params(&model, seed());
    let origins = [[0.0, 5.0, -3.0], [0.0, 0.0, -3.0], [3.0, 3.0, 3.0]];
    let dirs = [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
    let rgb = [[0.2, 0.3, 0.4]; 3];
    let mask = [0.0, 1.0, 0.0];
    let rays = RayBatch {
        origins: &origins,
        dirs: &dirs,
        codes: &[],
        p: &[],
    };
    let t = Targets {
        rgb: &rgb,
        mask: Some(&mask),
    };
    let sched = model.config.schedule(10);
    let mut g = vec![0f32; p.len()];
    let o = model
        .train_step(&p, &mut g, &rays, &t, sched, None, 1)
        .unwrap();
    assert_eq!(o.n_valid_rays, 1, "only the middle ray enters the box");
    assert!(o.total.is_finite() && all_finite(&g));
    // Occupancy grid with nothing occupied: no sample at all.
    let mut occ = OccupancyGrid::new(8, 1.0);
    occ.binary.fill(false);
    let mut g = vec![0f32; p.len()];
    let o = model
        .train_step(&p, &mut g, &rays, &t, sched, Some(&occ), 1)
        .unwrap();
    assert_eq!((o.n_samples, o.n_valid_rays), (0, 0));
    assert_eq!((o.rgb_l1, o.eikonal), (0.0, 0.0));
    assert!(o.total.is_finite() && all_finite(&g));
    // Only the mask loss remains, on opacity 0 clamped to 1e-3: −ln(1e-3) for the foreground
    // ray, −ln(1 − 1e-3) for each background ray; it has no parameter to reach.
    let want = (-(1e-3f64).ln() - 2.0 * (1.0 - 1e-3f64).ln()) / 3.0;
    assert!((o.mask - want).abs() < 1e-9, "{} vs {want}", o.mask);
    assert!(g.iter().all(|&v| v == 0.0));
    let r = model.render(&p, &rays, sched, Some(&occ)).unwrap();
    for i in 0..3 {
        assert_eq!(r.rgb[i], model.config.render.background);
        assert_eq!(
            (r.opacity[i], r.depth[i], r.normal[i]),
            (0.0, 0.0, [0.0; 3])
        );
    }
}

/// Deep inside everywhere (SDF bias −5) with a sharp inv_s: the first alpha is 1, the ray is
/// opaque and takes the first sample's colour; gradients stay finite.
#[test]
fn all_alphas_one() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let mut p = perturbed_params(&model, seed());
    let sdf = model.layout.group("sdf_mlp").unwrap();
    let last_bias = sdf.offset + sdf.len - model.config.field.sdf.feature_dim;
    p[last_bias] = -5.0;
    p[model.layout.group("variance").unwrap().offset] = 1.0; // inv_s = e^10
    let b = batch(8, 4);
    let rays = b.rays();
    let t = b.targets();
    let mut g = vec![0f32; p.len()];
    let o = model
        .train_step(&p, &mut g, &rays, &t, model.config.schedule(200), None, 1)
        .unwrap();
    assert!(o.total.is_finite() && all_finite(&g));
    let r = model
        .render(&p, &rays, model.config.inference_schedule(200), None)
        .unwrap();
    for i in 0..8 {
        assert!(
            (r.opacity[i] - 1.0).abs() < 1e-5,
            "ray {i} opacity {}",
            r.opacity[i]
        );
    }
}

/// Points on the box surface, edges and corners: finite SDF; a training ray running exactly
/// along a box edge (finite-difference taps clamped to the box) gives finite values.
#[test]
fn box_edges() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let p = perturbed_params(&model, seed());
    let pts = [
        [1.0, 1.0, 1.0],
        [-1.0, -1.0, -1.0],
        [1.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
    ];
    let s = model.sdf(&p, &pts, 4);
    assert!(all_finite(&s), "{s:?}");
    let origins = [[-3.0, 1.0, 1.0], [-1.0, -1.0, -1.0]];
    let dirs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let rgb = [[0.5; 3]; 2];
    let rays = RayBatch {
        origins: &origins,
        dirs: &dirs,
        codes: &[],
        p: &[],
    };
    let t = Targets {
        rgb: &rgb,
        mask: None,
    };
    let mut g = vec![0f32; p.len()];
    let o = model
        .train_step(&p, &mut g, &rays, &t, model.config.schedule(10), None, 1)
        .unwrap();
    assert_eq!(o.n_valid_rays, 2, "{o:?}");
    assert!(
        o.total.is_finite() && o.eikonal.is_finite() && all_finite(&g),
        "{o:?}"
    );
}

/// A huge learning step after a real training step: detected, reported, skipped; the
/// parameters stay finite and unchanged.
#[test]
fn huge_learning_step_is_skipped() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let mut p = perturbed_params(&model, seed());
    let b = batch(16, 5);
    let rays = b.rays();
    let t = b.targets();
    let mut g = vec![0f32; p.len()];
    model
        .train_step(&p, &mut g, &rays, &t, model.config.schedule(0), None, 1)
        .unwrap();
    let mut opt = AdamW::new(AdamWConfig::default(), p.len());
    let before = p.clone();
    let err = opt
        .step(&mut p, &g, &model.layout, f32::INFINITY)
        .unwrap_err();
    assert!(matches!(err, OptimError::NonFinite { .. }), "{err}");
    assert_eq!(p, before);
    opt.step(&mut p, &g, &model.layout, 1.0).unwrap();
    assert!(all_finite(&p) && p != before);
}

/// Batch validation names the offending input.
#[test]
fn bad_batches_are_errors() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let p = perturbed_params(&model, 1);
    let o = [[0.0, 0.0, -3.0]];
    let d = [[0.0, 0.0, 1.0]];
    let rays = RayBatch {
        origins: &o,
        dirs: &d,
        codes: &[7],
        p: &[],
    };
    let e = model
        .render(&p, &rays, model.config.schedule(0), None)
        .unwrap_err();
    assert!(e.to_string().contains("code 7"), "{e}");
    let nan = [[f32::NAN, 0.0, 0.0]];
    let rays = RayBatch {
        origins: &nan,
        dirs: &d,
        codes: &[],
        p: &[],
    };
    assert!(model
        .render(&p, &rays, model.config.schedule(0), None)
        .is_err());
    let rays = RayBatch {
        origins: &o,
        dirs: &d,
        codes: &[],
        p: &[],
    };
    let e = model
        .render(&p[1..], &rays, model.config.schedule(0), None)
        .unwrap_err();
    assert!(e.to_string().contains("parameter buffer"), "{e}");
}

/// Occupancy update through the model: a sphere-initialised SDF marks cells near the sphere of
/// radius 0.5 occupied and far cells empty.
#[test]
fn occupancy_update_finds_the_sphere() {
    let mut cfg = tiny_config();
    cfg.render.occupancy.resolution = 16;
    let model = NeusModel::new(cfg).unwrap();
    let mut p = model.init_params(3);
    p[model.layout.group("variance").unwrap().offset] = 0.5; // inv_s = e^5 ≈ 148
    let mut grid = model.new_occupancy_grid();
    assert!(!model.update_occupancy(&p, &mut grid, 3, model.config.schedule(3), 1));
    assert!(model.update_occupancy(&p, &mut grid, 0, model.config.schedule(0), 1));
    assert!(grid.is_occupied([0.0, 0.0, 0.0]), "inside is opaque");
    assert!(
        !grid.is_occupied([0.95, 0.95, 0.95]),
        "the box corner is empty"
    );
    let f = grid.occupied_fraction();
    assert!(f > 0.01 && f < 0.5, "occupied fraction {f}");
}

/// The learned background's density network output channel 0 (raw density) bias index.
fn bg_density_bias(model: &NeusModel) -> usize {
    let g = model.layout.group("bg_density").unwrap();
    let mlp = &model.background.as_ref().unwrap().density;
    g.offset
        + mlp.weight_offset(mlp.n_layers() - 1)
        + mlp.dims[mlp.n_layers() - 1] * mlp.dims[mlp.n_layers()]
}

/// The learned background on hard rays: through the box, starting inside it,
/// running along a box edge, grazing a corner, missing the box, pointing away from it. With zero
/// background density the render equals the model without a background (same foreground
/// parameters: the layouts share their prefix); with saturated density a ray that misses the
/// box takes the background network's colour; training values stay finite in both, and in
/// between.
#[test]
fn background_on_hard_rays() {
    let model = NeusModel::new(tiny_background_config()).unwrap();
    let plain = NeusModel::new(tiny_config()).unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let origins = [
        [0.0, 0.0, -3.0],
        [0.2, 0.1, 0.3],
        [-3.0, 1.0, 1.0],
        [-2.0, 0.0, 0.0],
        [0.0, 5.0, -3.0],
        [0.0, 0.0, 3.0],
    ];
    let dirs = [
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [s, s, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    ];
    let rgb = [[0.2, 0.3, 0.4]; 6];
    let rays = RayBatch {
        origins: &origins,
        dirs: &dirs,
        codes: &[],
        p: &[],
    };
    let t = Targets {
        rgb: &rgb,
        mask: None,
    };
    let sched = model.config.schedule(10);
    let mut p = perturbed_params(&model, seed());
    let bias = bg_density_bias(&model);
    let n_fg = plain.n_params();
    assert_eq!(
        &model.layout.groups[..5],
        &plain.layout.groups[..],
        "shared prefix"
    );
    for (raw, what) in [(-1e4f32, "zero"), (0.0, "moderate"), (1e4, "saturated")] {
        p[bias] = raw;
        let mut g = vec![0f32; p.len()];
        let o = model
            .train_step(&p, &mut g, &rays, &t, sched, None, 1)
            .unwrap();
        assert_eq!(
            o.n_valid_rays, 6,
            "{what}: every ray has background samples"
        );
        assert!(o.total.is_finite() && all_finite(&g), "{what}: {o:?}");
        let r = model.render(&p, &rays, sched, None).unwrap();
        let c_bg = model.render_background(&p, &rays).unwrap();
        assert!(
            r.rgb
                .iter()
                .chain(&c_bg)
                .flatten()
                .all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
            "{what}: {r:?}"
        );
        if what == "zero" {
            let rp = plain.render(&p[..n_fg], &rays, sched, None).unwrap();
            for (i, (a, b)) in r.rgb.iter().zip(&rp.rgb).enumerate() {
                for k in 0..3 {
                    assert!((a[k] - b[k]).abs() < 1e-6, "ray {i}: {r:?} vs {rp:?}");
                }
                assert_eq!(c_bg[i], model.config.render.background);
            }
            // No background gradient reaches the density network through a zero density
            // (softplus' slope at −1e4 underflows), but the loss still trains the foreground.
        }
        if what == "saturated" {
            // Rays 4 and 5 miss the box: their colour is the background network's first sample.
            for i in [4, 5] {
                assert_eq!(r.opacity[i], 0.0);
                assert_eq!(r.rgb[i], c_bg[i]);
                assert_ne!(c_bg[i], model.config.render.background, "ray {i}");
            }
        }
    }
    // Without a background there is nothing to render.
    let err = plain.render_background(&p[..n_fg], &rays).unwrap_err();
    assert!(err.to_string().contains("model.background.kind"), "{err}");
}
