//! The full training loss's gradient against central differences, in f64, for a random subset
//! of every parameter group; plus f32/f64 agreement and determinism of the f32 path.

mod field_common;

use field_common::{batch, perturbed_params, seed, tiny_background_config, tiny_config};
use neus_aug::render::NeusModel;
use neus_aug::train::TrainStep;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

#[test]
fn full_loss_gradient_matches_central_differences() {
    check_full_gradient(tiny_config());
}

/// The recipe terms on top of the default losses: curvature (Laplacian from the
/// taps and the centre), NeuS-style colour loss inside the mask, and both mask BCE forms.
#[test]
fn recipe_loss_gradients_match_central_differences() {
    use neus_aug::render::{MaskBce, Scheduled};
    for (bce, in_mask) in [(MaskBce::Squash, true), (MaskBce::Clamp, false)] {
        let mut cfg = tiny_config();
        cfg.loss.curvature = Scheduled::Constant(0.05);
        cfg.loss.mask_bce = bce;
        cfg.loss.color_in_mask = in_mask;
        let out = check_full_gradient(cfg);
        assert!(out.curvature > 0.0, "{out:?}");
    }
}

/// Forward differences (`render.fd_central_every = 3`): without the curvature loss
/// every sample takes three forward taps; with it every third sample takes central ones and
/// carries the curvature term, weighted 3. Both backward passes against central differences of
/// the loss in f64, and the forward scheme really is in use (the eikonal term differs from the
/// all-central one).
#[test]
fn forward_difference_gradients_match_central_differences() {
    use neus_aug::render::Scheduled;
    let s = seed();
    let eikonal_of = |cfg: neus_aug::render::ModelConfig| {
        let model = NeusModel::new(cfg).unwrap();
        let p = perturbed_params_f64(&model, s);
        let b = batch(24, s + 1);
        let mut g = vec![0.0; p.len()];
        model
            .train_step(
                &p,
                &mut g,
                &b.rays(),
                &b.targets(),
                model.config.schedule(40),
                None,
                99,
            )
            .unwrap()
    };
    for curvature in [0.0, 0.05] {
        let mut cfg = tiny_config();
        cfg.loss.curvature = Scheduled::Constant(curvature);
        let central = eikonal_of(cfg.clone());
        cfg.render.fd_central_every = 3;
        let out = check_full_gradient(cfg.clone());
        assert!(
            (out.eikonal - central.eikonal).abs() > 1e-9 * central.eikonal.abs(),
            "forward differences changed nothing: {} vs {}",
            out.eikonal,
            central.eikonal
        );
        // The one-sided span (taps at x ± 2ε·e_a, divided by 2ε): its backward too, and it is
        // in use (the eikonal term moves again).
        let mut wide = cfg.clone();
        wide.render.fd_one_sided_span = 2.0;
        let out2 = check_full_gradient(wide);
        assert!(
            (out2.eikonal - out.eikonal).abs() > 1e-9 * out.eikonal.abs(),
            "the span changed nothing: {} vs {}",
            out2.eikonal,
            out.eikonal
        );
        assert_eq!(out.n_samples, central.n_samples);
        if curvature > 0.0 {
            // A third of the samples, weighted 3: the same mean |Δf| up to sampling.
            let ratio = out.curvature / central.curvature;
            assert!(
                (0.5..2.0).contains(&ratio),
                "curvature {out:?} vs {central:?}"
            );
        } else {
            assert_eq!(out.curvature, 0.0);
        }
    }
}

/// Renders use central differences whatever `render.fd_central_every` says: the same bits.
#[test]
fn renders_ignore_the_training_tap_layout() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let mut cfg = tiny_config();
    cfg.render.fd_central_every = 4;
    let fwd = NeusModel::new(cfg).unwrap();
    let s = seed();
    let p = perturbed_params(&model, s);
    let b = batch(16, s + 3);
    let rays = b.rays();
    let a = model
        .render(&p, &rays, model.config.schedule(50), None)
        .unwrap();
    let c = fwd
        .render(&p, &rays, fwd.config.schedule(50), None)
        .unwrap();
    for r in 0..rays.origins.len() {
        for k in 0..3 {
            assert_eq!(a.rgb[r][k].to_bits(), c.rgb[r][k].to_bits(), "ray {r}");
            assert_eq!(
                a.normal[r][k].to_bits(),
                c.normal[r][k].to_bits(),
                "ray {r}"
            );
        }
    }
    let mut bad = tiny_config();
    bad.render.fd_central_every = 0;
    assert!(NeusModel::new(bad).is_err());
    for span in [0.0, 0.1, 2.5, f32::NAN] {
        let mut bad = tiny_config();
        bad.render.fd_one_sided_span = span;
        let e = NeusModel::new(bad).err().map(|e| e.to_string());
        assert!(
            e.as_deref()
                .is_some_and(|e| e.contains("fd_one_sided_span")),
            "span {span}: {e:?}"
        );
    }
}

/// The learned background: its two networks join the check, through the two-layer
/// compositing `C = C_fg + (1 − O_fg)·C_bg`; every ray counts as valid.
#[test]
fn background_gradient_matches_central_differences() {
    let out = check_full_gradient(tiny_background_config());
    assert_eq!(out.n_valid_rays, out.n_rays, "{out:?}");
}

/// Coarse-to-fine levels (2 of the tiny grid's 6 active at the checked step): the inactive
/// levels contribute nothing, the finite-difference epsilon follows the finest active level, and
/// the gradient (curvature term included) still matches central differences.
#[test]
fn progressive_levels_gradient_matches_central_differences() {
    use neus_aug::field::config::ProgressiveConfig;
    use neus_aug::render::Scheduled;
    let mut cfg = tiny_config();
    cfg.field.hash_grid.progressive = Some(ProgressiveConfig {
        start_level: 2,
        start_step: 0,
        update_steps: 1000,
    });
    cfg.loss.curvature = Scheduled::Constant(0.05);
    let model = NeusModel::new(cfg.clone()).unwrap();
    assert_eq!(model.config.schedule(40).active_levels, 2);
    let full = NeusModel::new(tiny_config()).unwrap();
    assert!(
        model.fd_eps(2) > full.fd_eps(6),
        "epsilon follows the finest active level"
    );
    check_full_gradient(cfg);
}

/// The view-dependence ramp (`render.view_dependence`) at 0.4 of the way: the colour
/// network's direction terms are scaled, and the gradient of every group still matches.
#[test]
fn view_dependence_ramp_gradient_matches_central_differences() {
    use neus_aug::render::Scheduled;
    let mut cfg = tiny_config();
    cfg.render.view_dependence = Scheduled::Linear(0, 0.0, 1.0, 100);
    let model = NeusModel::new(cfg.clone()).unwrap();
    assert!((model.config.schedule(40).view_dependence - 0.4).abs() < 1e-6);
    check_full_gradient(cfg);
}

/// With `view_dependence = 0` the renderer equals, to rounding, a colour network whose weights
/// on the direction terms (spherical-harmonic degrees 1–3) are zero: the view direction has no
/// effect. And the knob does something: at 1 the renders differ.
#[test]
fn zero_view_dependence_removes_the_direction_from_the_colour() {
    use neus_aug::render::Scheduled;
    let mut cfg = tiny_config();
    cfg.render.view_dependence = Scheduled::Constant(0.0);
    let model = NeusModel::new(cfg.clone()).unwrap();
    let s = seed();
    let p = perturbed_params(&model, s);
    let b = batch(16, s + 3);
    let rays = b.rays();
    let at0 = model
        .render(&p, &rays, model.config.schedule(50), None)
        .unwrap();
    // The same parameters with the first colour layer's direction columns zeroed (W is
    // `[out][in]` row-major; input columns `feature_dim + 1 .. feature_dim + 16`).
    let mut q = p.clone();
    let grp = model.layout.group("color_mlp").unwrap();
    let dc = cfg.field.color_input_dim();
    let fdim = cfg.field.sdf.feature_dim;
    for o in 0..cfg.field.color.n_neurons {
        for k in fdim + 1..fdim + 16 {
            q[grp.offset + o * dc + k] = 0.0;
        }
    }
    let mut full = cfg.clone();
    full.render.view_dependence = Scheduled::Constant(1.0);
    let model1 = NeusModel::new(full).unwrap();
    let zeroed = model1
        .render(&q, &rays, model1.config.schedule(50), None)
        .unwrap();
    let with_dirs = model1
        .render(&p, &rays, model1.config.schedule(50), None)
        .unwrap();
    let mut differs = 0.0f32;
    for r in 0..rays.origins.len() {
        for k in 0..3 {
            assert!(
                (at0.rgb[r][k] - zeroed.rgb[r][k]).abs() < 1e-5,
                "ray {r}: {:?} vs {:?}",
                at0.rgb[r],
                zeroed.rgb[r]
            );
            differs = differs.max((at0.rgb[r][k] - with_dirs.rgb[r][k]).abs());
        }
        assert!(at0.rgb[r].iter().all(|v| v.is_finite()));
    }
    assert!(
        differs > 1e-3,
        "the direction terms had no effect: {differs}"
    );
}

/// Central difference (step 1e-6) of `loss` in parameter `i` of `p` (restored afterwards).
/// [`perturbed_params`] widened to f64, for the f64 gradient checks.
fn perturbed_params_f64(model: &NeusModel, seed: u64) -> Vec<f64> {
    perturbed_params(model, seed)
        .iter()
        .map(|&v| v as f64)
        .collect()
}

fn central_difference(p: &mut [f64], i: usize, loss: impl Fn(&[f64]) -> f64) -> f64 {
    let h = 1e-6;
    let old = p[i];
    p[i] = old + h;
    let lp = loss(p);
    p[i] = old - h;
    let lm = loss(p);
    p[i] = old;
    (lp - lm) / (2.0 * h)
}

fn check_full_gradient(cfg: neus_aug::render::ModelConfig) -> neus_aug::train::StepOutput {
    let model = NeusModel::new(cfg).unwrap();
    let s = seed();
    let p32 = perturbed_params(&model, s);
    let mut p: Vec<f64> = p32.iter().map(|&v| v as f64).collect();
    let b = batch(24, s + 1);
    let rays = b.rays();
    let targets = b.targets();
    let sched = model.config.schedule(40); // cos anneal 0.4: both anneal branches active
    let step_seed = 99;
    let mut grads = vec![0.0f64; p.len()];
    let out = model
        .train_step(&p, &mut grads, &rays, &targets, sched, None, step_seed)
        .unwrap();
    assert!(out.n_samples > 100 && out.n_valid_rays > 10, "{out:?}");
    assert!(out.eikonal > 0.0 && out.mask > 0.0 && out.rgb_l1 > 0.0);

    let loss = |p: &[f64]| {
        let mut g = vec![0.0; p.len()];
        model
            .train_step(p, &mut g, &rays, &targets, sched, None, step_seed)
            .unwrap()
            .total
    };
    let mut rng = Pcg64Mcg::seed_from_u64(s + 2);
    let mut fails = Vec::new();
    let mut checked = Vec::new();
    for grp in model.layout.groups.clone() {
        let r = grp.range();
        let nonzero: Vec<usize> = r.clone().filter(|&i| grads[i] != 0.0).collect();
        let mut idx: Vec<usize> = (0..12).map(|_| rng.random_range(r.clone())).collect();
        idx.extend((0..12.min(nonzero.len())).map(|_| nonzero[rng.random_range(0..nonzero.len())]));
        idx.sort_unstable();
        idx.dedup();
        let mut n_nonzero = 0;
        for i in idx {
            let fd = central_difference(&mut p, i, loss);
            let an = grads[i];
            if an != 0.0 {
                n_nonzero += 1;
            }
            let scale = fd.abs().max(an.abs());
            if (fd - an).abs() > 1e-7 + 1e-4 * scale {
                fails.push(format!(
                    "{}[{}]: analytic {an:.9e} fd {fd:.9e}",
                    grp.name,
                    i - r.start
                ));
            }
        }
        checked.push(format!("{} ({} nonzero)", grp.name, n_nonzero));
        assert!(n_nonzero > 0, "group {} received no gradient", grp.name);
    }
    assert!(
        fails.is_empty(),
        "gradient mismatches ({}):\n{}\nchecked: {checked:?}",
        fails.len(),
        fails.join("\n")
    );
    out
}

#[test]
fn f32_path_agrees_with_f64_and_is_deterministic() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let s = seed();
    let p32 = perturbed_params(&model, s);
    let p64: Vec<f64> = p32.iter().map(|&v| v as f64).collect();
    let b = batch(32, s + 5);
    let rays = b.rays();
    let targets = b.targets();
    let sched = model.config.schedule(1000);
    let mut g32 = vec![0f32; p32.len()];
    let o32 = model
        .train_step(&p32, &mut g32, &rays, &targets, sched, None, 7)
        .unwrap();
    let mut g64 = vec![0f64; p64.len()];
    let o64 = model
        .train_step(&p64, &mut g64, &rays, &targets, sched, None, 7)
        .unwrap();
    assert!(
        (o32.total - o64.total).abs() < 1e-4 * o64.total.abs().max(1.0),
        "{} vs {}",
        o32.total,
        o64.total
    );
    let gmax = g64.iter().fold(0f64, |a, &b| a.max(b.abs()));
    let worst = g32
        .iter()
        .zip(&g64)
        .map(|(&a, &b)| (a as f64 - b).abs())
        .fold(0f64, f64::max);
    assert!(
        worst < 2e-3 * gmax,
        "f32 vs f64 gradient: worst {worst}, max {gmax}"
    );
    // Same inputs, same bits (parallel shards, fixed reduction order).
    for _ in 0..3 {
        let mut g = vec![0f32; p32.len()];
        let o = model
            .train_step(&p32, &mut g, &rays, &targets, sched, None, 7)
            .unwrap();
        assert_eq!(o.total.to_bits(), o32.total.to_bits());
        assert!(
            g.iter().zip(&g32).all(|(a, b)| a.to_bits() == b.to_bits()),
            "gradient bits differ"
        );
    }
}

/// For a loss of the SDF channel at points: only the `hash_grid` and `sdf_mlp` groups get a
/// gradient, and 8 random plus up to 16 nonzero entries of each group match central differences
/// within `abs + 1e-5·relative`.
fn check_sdf_group_gradients(
    model: &NeusModel,
    p: &mut [f64],
    grads: &[f64],
    loss: impl Fn(&[f64]) -> f64 + Copy,
    abs: f64,
    rng: &mut Pcg64Mcg,
) {
    let mut fails = Vec::new();
    for grp in model.layout.groups.clone() {
        let r = grp.range();
        let nonzero: Vec<usize> = r.clone().filter(|&i| grads[i] != 0.0).collect();
        let fitted = grp.name == "hash_grid" || grp.name == "sdf_mlp";
        assert_eq!(!nonzero.is_empty(), fitted, "group {}", grp.name);
        let mut idx: Vec<usize> = (0..8).map(|_| rng.random_range(r.clone())).collect();
        idx.extend((0..16.min(nonzero.len())).map(|_| nonzero[rng.random_range(0..nonzero.len())]));
        for i in idx {
            let fd = central_difference(p, i, loss);
            if (fd - grads[i]).abs() > abs + 1e-5 * fd.abs().max(grads[i].abs()) {
                fails.push(format!(
                    "{}[{}]: analytic {:e} fd {fd:e}",
                    grp.name,
                    i - r.start,
                    grads[i]
                ));
            }
        }
    }
    assert!(fails.is_empty(), "{}", fails.join("\n"));
}

/// The visual-hull fit's loss: mean |f(x) − t| of the SDF channel, its gradient through
/// the SDF network and the hash grid against central differences in f64, with 2 of the tiny
/// grid's 4 levels active (as the fit runs with the levels of training step 0). Targets are far
/// from the field's values so no term sits at the kink of |·|. No other group gets a gradient.
#[test]
fn sdf_fit_gradient_matches_central_differences() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let s = seed();
    let mut p = perturbed_params_f64(&model, s);
    let mut rng = Pcg64Mcg::seed_from_u64(s + 7);
    let pts: Vec<[f64; 3]> = (0..40)
        .map(|_| [0; 3].map(|_| rng.random_range(-0.95..0.95)))
        .collect();
    let active = 2;
    let targets: Vec<f64> = (0..pts.len())
        .map(|i| if i % 2 == 0 { 50.0 } else { -50.0 })
        .collect();
    let mut grads = vec![0.0; p.len()];
    let l = model.sdf_fit_loss_grad(&p, &pts, &targets, active, &mut grads);
    assert!(l > 40.0, "{l}");
    let loss = |p: &[f64]| {
        let mut g = vec![0.0; p.len()];
        model.sdf_fit_loss_grad(p, &pts, &targets, active, &mut g)
    };
    check_sdf_group_gradients(&model, &mut p, &grads, loss, 1e-8, &mut rng);
    // Inactive levels (3 and 4) get nothing: all four levels reach more table entries.
    let g0 = model.layout.group("hash_grid").unwrap().range();
    let mut g4 = vec![0.0; p.len()];
    model.sdf_fit_loss_grad(&p, &pts, &targets, 4, &mut g4);
    let more = g0.clone().filter(|&i| g4[i] != 0.0).count();
    let fewer = g0.filter(|&i| grads[i] != 0.0).count();
    assert!(more > fewer, "{more} vs {fewer}");
}

/// The depth prior's loss (`train::depth::carve_loss_grad`) on a fixed plan: a hinge `max(0, τ − f)` on each carved span's points (some above τ, so no term) and
/// `|f|` at the surface point. Against central differences in f64, and against the loss
/// written out; points are held a margin away from the hinge's and `|f|`'s kinks.
#[test]
fn carve_gradient_matches_central_differences() {
    use neus_aug::train::depth::{carve_loss_grad, CarvedRay};
    let model = NeusModel::new(field_common::tiny_config()).unwrap();
    let s = seed();
    let mut p = perturbed_params_f64(&model, s);
    let mut rng = Pcg64Mcg::seed_from_u64(s + 17);
    let active = 3;
    let value = |p: &[f64], x: [f64; 3]| {
        let mut g = vec![0.0; p.len()];
        model.sdf_weighted_grad(p, &[x], &[0.0], active, &mut g)[0]
    };
    let mut pick = |p: &[f64]| loop {
        let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.6..0.6));
        let f = value(p, x);
        // τ on either side of f, at least 1e-3 away, so the hinge's state holds.
        let tau = f + if rng.random_bool(0.6) { 0.02 } else { -0.02 };
        if f.abs() > 1e-3 && tau > 0.0 {
            return (x, tau);
        }
    };
    let plan: Vec<CarvedRay> = (0..5)
        .map(|i| CarvedRay {
            t: 0.1 * i as f64,
            t_b: 0.1 * i as f64 + 0.2,
            free: (0..3 + i).map(|_| pick(&p)).collect(),
            // Some spans lost points to the other views' confirmation.
            span: 3 + i + i % 2,
            surface: pick(&p).0,
            // One ray's depth found no other view to agree with it.
            pull: i != 2,
        })
        .collect();
    let (weight, surface_weight) = (0.7, 0.5);
    let eval = |q: &[f64]| {
        let q = q.to_vec();
        let m = &model;
        move |pts: &[[f64; 3]]| {
            let mut g = vec![0.0; q.len()];
            m.sdf_weighted_grad(&q, pts, &vec![0.0; pts.len()], active, &mut g)
        }
    };
    let mut grads = vec![0.0; p.len()];
    let l = carve_loss_grad(
        weight,
        surface_weight,
        &model,
        &p,
        &eval(&p),
        &plan,
        active,
        &mut grads,
    );
    let by_hand: f64 = plan
        .iter()
        .map(|c| {
            let hinge = c
                .free
                .iter()
                .map(|&(x, tau)| (tau - value(&p, x)).max(0.0))
                .sum::<f64>()
                / c.span as f64;
            let pull = if c.pull { 0.5 } else { 0.0 };
            0.7 * (hinge + pull * value(&p, c.surface).abs()) / plan.len() as f64
        })
        .sum();
    assert!(
        l > 0.0 && (l - by_hand).abs() < 1e-6 * by_hand,
        "{l} vs {by_hand}"
    );
    let loss = |q: &[f64]| {
        let mut g = vec![0.0; q.len()];
        carve_loss_grad(
            weight,
            surface_weight,
            &model,
            q,
            &eval(q),
            &plan,
            active,
            &mut g,
        )
    };
    check_sdf_group_gradients(&model, &mut p, &grads, loss, 1e-9, &mut rng);
    // An empty plan: no loss, no gradient.
    let mut g = vec![0.0; p.len()];
    assert_eq!(
        carve_loss_grad(
            weight,
            surface_weight,
            &model,
            &p,
            &eval(&p),
            &[],
            active,
            &mut g
        ),
        0.0
    );
    assert!(g.iter().all(|&v| v == 0.0));
}
