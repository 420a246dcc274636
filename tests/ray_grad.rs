//! The loss's gradient with respect to each ray's origin and direction
//! (`NeusModel::forward_backward_rays`, pose refinement's input) against central differences of
//! the full training loss in f64.
//!
//! The renderer holds the sample distances `t` fixed; so do these rays: their origins lie inside
//! the box, where marching starts at `t = 0` whatever the origin, and each ray's jitter is fixed
//! by the step seed. Origins and directions are multiples of 2⁻¹² and the step is 2⁻¹⁶, so the
//! perturbed rays are exact in the batch's f32.

// The checks index rays and components of several parallel arrays.
#![allow(clippy::needless_range_loop)]

mod field_common;

use field_common::{perturbed_params, seed, tiny_config, Batch};
use neus_aug::render::{mark_ray_grad, ray_grad, ModelConfig, NeusModel, RayGradCell};
use neus_aug::train::{StepSinks, TrainStep};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn quantise(v: f64) -> f32 {
    ((v * 4096.0).round() / 4096.0) as f32
}

/// `n` rays from inside the box (`[-0.7, 0.7]³`), random directions, targets, masks, codes, p.
fn inside_rays(n: usize, seed: u64) -> Batch {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut b = Batch::default();
    for _ in 0..n {
        b.origins
            .push([0; 3].map(|_| quantise(rng.random_range(-0.7..0.7))));
        let d: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(0.2);
        b.dirs.push(d.map(|v| quantise(v / l)));
        b.rgb.push([rng.random(), rng.random(), rng.random()]);
        b.mask.push(if rng.random::<bool>() { 1.0 } else { 0.0 });
        b.codes.push(rng.random_range(0..3));
        b.p.push(rng.random_range(-0.5..0.5));
    }
    b
}

/// Component `k` of ray `r`'s origin (`what = "o"`) or direction.
fn component<'a>(b: &'a mut Batch, what: &str, r: usize, k: usize) -> &'a mut f32 {
    if what == "o" {
        &mut b.origins[r][k]
    } else {
        &mut b.dirs[r][k]
    }
}

fn cells(n: usize) -> Vec<RayGradCell> {
    (0..n).map(|_| Default::default()).collect()
}

/// Checks every component of `∂L/∂o` and `∂L/∂d` of every ray; returns the largest relative
/// error over the components whose difference quotient is not disturbed by a kink.
fn check_ray_gradients(cfg: ModelConfig) -> f64 {
    let model = NeusModel::new(cfg).unwrap();
    let s = seed();
    let p: Vec<f64> = perturbed_params(&model, s)
        .iter()
        .map(|&v| v as f64)
        .collect();
    let mut b = inside_rays(16, s + 3);
    let sched = model.config.schedule(40);
    let step_seed = 7;
    let sinks_cells = cells(b.origins.len());
    let mut g_rays = vec![0.0f64; p.len()];
    let out = {
        let sinks = StepSinks {
            ray_errors: None,
            ray_grads: Some(&sinks_cells),
        };
        let (rays, targets) = (b.rays(), b.targets());
        model
            .train_step_recording(
                &p,
                &mut g_rays,
                &rays,
                &targets,
                sched,
                None,
                step_seed,
                sinks,
            )
            .unwrap()
    };
    assert!(out.n_samples > 100, "{out:?}");
    // Asking for the rays' gradient changes no parameter gradient's bits.
    let mut g = vec![0.0f64; p.len()];
    model
        .train_step(&p, &mut g, &b.rays(), &b.targets(), sched, None, step_seed)
        .unwrap();
    assert!(g
        .iter()
        .zip(&g_rays)
        .all(|(a, b)| a.to_bits() == b.to_bits()));

    let h = 1.0 / 65536.0;
    let loss = |b: &Batch| {
        let mut g = vec![0.0; p.len()];
        let o = model
            .train_step(&p, &mut g, &b.rays(), &b.targets(), sched, None, step_seed)
            .unwrap();
        assert_eq!(o.n_samples, out.n_samples, "the samples moved");
        o.total
    };
    let mut fails = Vec::new();
    let mut errors = Vec::new();
    let mut n_big = 0;
    for r in 0..b.origins.len() {
        let (go, gd) = ray_grad(&sinks_cells[r]);
        for (what, an) in [("o", go), ("d", gd)] {
            for k in 0..3 {
                let old = *component(&mut b, what, r, k);
                *component(&mut b, what, r, k) = old + h as f32;
                let lp = loss(&b);
                *component(&mut b, what, r, k) = old - h as f32;
                let lm = loss(&b);
                *component(&mut b, what, r, k) = old;
                let fd = (lp - lm) / (2.0 * h);
                let scale = fd.abs().max(an[k].abs());
                if scale > 1e-4 {
                    n_big += 1;
                }
                let err = (fd - an[k]).abs() / (scale + 1e-6);
                errors.push(err);
                if (fd - an[k]).abs() > 1e-6 + 1e-3 * scale {
                    fails.push(format!(
                        "ray {r} {what}[{k}]: analytic {:.9e} fd {fd:.9e}",
                        an[k]
                    ));
                }
            }
        }
    }
    assert!(fails.is_empty(), "{}", fails.join("\n"));
    assert!(n_big > 40, "only {n_big} components carry a gradient");
    errors.sort_by(f64::total_cmp);
    // Most components agree to far better than the tolerance: a kink of the hash encoding or
    // an activation within one step explains a few, a wrong path would show everywhere.
    let median = errors[errors.len() / 2];
    assert!(median < 1e-6, "median relative error {median:e}");
    median
}

#[test]
fn ray_gradients_match_central_differences() {
    check_ray_gradients(tiny_config());
}

/// One-sided taps on two samples of three (`render.fd_central_every = 3`): the unused side's
/// rows carry nothing, the used taps move with the sample.
#[test]
fn ray_gradients_with_forward_differences_match_central_differences() {
    let mut cfg = tiny_config();
    cfg.render.fd_central_every = 3;
    check_ray_gradients(cfg);
}

/// A gradient buffer of the wrong length is refused by name.
#[test]
fn ray_gradient_cells_of_the_wrong_length_are_refused() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let p = perturbed_params(&model, seed());
    let b = inside_rays(4, 1);
    let c = cells(3);
    let mut g = vec![0.0f32; p.len()];
    let err = model
        .train_step_recording(
            &p,
            &mut g,
            &b.rays(),
            &b.targets(),
            model.config.schedule(0),
            None,
            0,
            StepSinks {
                ray_errors: None,
                ray_grads: Some(&c),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("ray_grads"), "{err}");
}

/// Cells marked as not wanted (`mark_ray_grad(cell, false)`) come back zero, the others with
/// the bits every-ray differentiation gives them, and the parameters' gradient is unchanged.
#[test]
fn unwanted_ray_gradients_are_zero_and_the_others_unchanged() {
    let model = NeusModel::new(tiny_config()).unwrap();
    let p = perturbed_params(&model, seed());
    let b = inside_rays(16, seed() + 5);
    let sched = model.config.schedule(40);
    let run = |wanted: &dyn Fn(usize) -> bool| {
        let c = cells(16);
        for (r, cell) in c.iter().enumerate() {
            mark_ray_grad(cell, wanted(r));
        }
        let mut g = vec![0.0f32; p.len()];
        model
            .train_step_recording(
                &p,
                &mut g,
                &b.rays(),
                &b.targets(),
                sched,
                None,
                7,
                StepSinks {
                    ray_errors: None,
                    ray_grads: Some(&c),
                },
            )
            .unwrap();
        (c.iter().map(ray_grad).collect::<Vec<_>>(), g)
    };
    let (all, g_all) = run(&|_| true);
    let (some, g_some) = run(&|r| r % 3 == 0);
    assert!(g_all
        .iter()
        .zip(&g_some)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let mut nonzero = 0;
    for r in 0..16 {
        if r % 3 == 0 {
            assert_eq!(some[r], all[r], "ray {r}");
            nonzero += usize::from(all[r].0.iter().any(|&v| v != 0.0));
        } else {
            assert_eq!(some[r], ([0.0; 3], [0.0; 3]), "ray {r}");
        }
    }
    assert!(nonzero >= 3, "the wanted rays have gradients");
}
