//! The presets of a `reconstruct` run: named starting points for every option of
//! [`RunConfig`], and the curvature schedule they share ([`delayed_curvature`]).

use super::config::{DataConfig, EvalConfig, MeshConfig, Preset, RunConfig};
use crate::augment::AugmentConfig;
use crate::field::config::ProgressiveConfig;
use crate::render::occupancy::{decay_for_run, rescale_decay};
use crate::render::{ModelConfig, Scheduled};
use crate::train::hull::InitKind;
use crate::train::TrainConfig;
use std::path::PathBuf;

/// Training steps of the `quick` preset (`fast` has 2000).
pub const QUICK_ITERATIONS: u64 = 1400;

impl Default for RunConfig {
    fn default() -> Self {
        Preset::Default.config()
    }
}

impl Preset {
    /// The full configuration of this preset.
    ///
    /// `paper` is instant-nsr-pl's `neus-dtu-wmask.yaml` (20000 steps, T = 2^19, 1024 samples per
    /// ray, 256 → 8192 rays, cos anneal over the whole run, constant learning rate for 5000 steps
    /// then decay to 0.1×, 512³ marching cubes, DTU images at half size). `default` and `fast`
    /// shrink the hash table (it no longer fits a CPU's cache at 2^19), the sample budget, the
    /// step count and the occupancy grid, and warm the learning rate up briefly because short
    /// runs start with few rays.
    pub fn config(self) -> RunConfig {
        let mut model = ModelConfig::default();
        let mut train = TrainConfig::default();
        let mut data = DataConfig::default();
        let mut mesh = MeshConfig::default();
        match self {
            Preset::Paper => {
                data.downscale = 2;
                data.render_downscale = 1;
                // instant-nsr-pl `configs/neus-dtu.yaml` (ProgressiveBandHashGrid): 4 levels at
                // first, one more every 1000 steps.
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 1000,
                });
                // The reference has no depth prior, so no switch that turns one on
                // (`train::depth_auto`).
                train.depth.auto.enabled = false;
            }
            Preset::Default => {
                model.field.hash_grid.log2_hashmap_size = 17;
                model.render.num_samples_per_ray = 512;
                model.render.train_num_rays = 128;
                model.render.max_train_num_rays = 4096;
                model.render.occupancy.resolution = 64;
                train.iterations = 8000;
                // The same coarse-to-fine schedule as `paper`, on the preset's step count: every
                // level active after 60 % of training (cleaner topology, and inactive levels
                // cost nothing).
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 400,
                });
                train.lr.constant_steps = 2000;
                train.lr.warmup_steps = 200;
                train.checkpoint_every = 500;
                model.render.cos_anneal_end = 8000;
                mesh.coarse_res = 128;
                mesh.fine_res = 512;
            }
            Preset::Fast => {
                model.field.hash_grid.log2_hashmap_size = 16;
                model.render.num_samples_per_ray = 256;
                model.render.train_num_rays = 128;
                // With the scaled decay below the grid skips so much empty space that a ray keeps
                // only 4–9 of its 256 samples on thin or holed shapes, and the cap decides how
                // much of the 32 768-sample budget per step is spent; a lower cap leaves most of
                // it unspent on such shapes (measured: docs/recipe.md). 64× the start: the
                // reference has 32× (8192 / 256), but at 1024 samples per ray its budget reaches
                // the cap only below 32 samples per ray, ours below 4.
                model.render.max_train_num_rays = 8192;
                model.render.occupancy.resolution = 48;
                train.iterations = 2000;
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 100,
                });
                // The grid forgets at the reference's pace per fraction of the run (0.599 per
                // update, `decay_for_run`): holes open more often (measured: docs/recipe.md).
                // `default` keeps 0.95 until a run measures 0.88 there (1 h 45 min on 2 cores).
                model.render.occupancy.ema_decay = decay_for_run(train.iterations);
                train.lr.constant_steps = 500;
                train.lr.warmup_steps = 100;
                train.checkpoint_every = 250;
                model.render.cos_anneal_end = 2000;
                data.render_downscale = 2;
                mesh.coarse_res = 96;
                mesh.fine_res = 256;
                // Half the rays where the colour error is high (instant-ngp's error map,
                // `train::error_map`), and the closing that fills the sub-millimetre tunnels
                // the map leaves through thin sheets (`mesh::closing`). The map lowers the mean
                // ratio to the floor over the built-in scenes; the closing removes the handles it
                // adds (measured: docs/recipe.md).
                train.error_map.share = 0.5;
                mesh.close_radius = 1;
                // One-sided finite differences over 2ε (`render.fd_one_sided_span`) on every
                // sample before the curvature ramp and on three in four during it: a step with
                // fewer taps, about 1.1× faster at the accuracy of central differences
                // (measured: docs/recipe.md).
                model.render.fd_central_every = 4;
                model.render.fd_one_sided_span = 2.0;
            }
            Preset::Quick => {
                // `fast` shortened to 1400 steps, every schedule kept at its fraction of the run:
                // a short time to mesh at under 1 mm on the default scene (measured:
                // docs/recipe.md).
                let mut c = scale_run_length(&Preset::Fast.config(), QUICK_ITERATIONS);
                // The decay straight from the reference rather than rescaled from fast's f32.
                c.model.render.occupancy.ema_decay = decay_for_run(QUICK_ITERATIONS);
                // 128 samples per ray halve the cost of a step; half-size training images (a
                // 1600×1200 DTU view becomes 800×600, the reference's own size, instant-nsr-pl
                // `configs/neus-dtu.yaml` `img_downscale: 2`) give back the accuracy 128 samples
                // lose (measured: docs/recipe.md).
                c.preset = Preset::Quick;
                // `quick` keeps the uniform sampler and the raw level set: its time-to-mesh
                // figures were measured so, and the map was not run at 1400 steps.
                c.train.error_map = Default::default();
                c.mesh.close_radius = 0;
                // Central differences too, for the same reason (one-sided ones over ε, given the
                // steps their speed buys, lost to central ones).
                c.model.render.fd_central_every = 1;
                c.model.render.fd_one_sided_span = 1.0;
                c.model.render.num_samples_per_ray = 128;
                c.data.downscale = 2;
                // Held-out views at fast's resolution, so PSNR and normal error compare.
                c.data.render_downscale = 1;
                // The depth prior's automatic switch a quarter into the run (step 350): at step
                // 200, where a tenth of 1400 steps and `min_step` put it, the front of an object
                // without a cavity has not settled on half-size images and comes close to the
                // switch's 5 % threshold; at step 350 it has (measured: docs/recipe.md).
                c.train.depth.auto.at = 0.25;
                return c;
            }
        }
        model.loss.curvature = delayed_curvature(train.iterations);
        if self != Preset::Paper {
            // The sphere start, unless the masks carve most of the init sphere away: then the
            // visual hull's, which keeps a frame of thin rods from turning to fog (`train::hull`
            // module docs; measured: docs/recipe.md). Scenes that fill the sphere train bit for
            // bit as before. `paper` keeps the reference's sphere.
            train.init.kind = InitKind::SphereOrHull;
        }
        RunConfig {
            preset: self,
            scene: String::new(),
            data_root: PathBuf::from("data/dtu"),
            out: None,
            seed: 0,
            data,
            augment: AugmentConfig::default(),
            model,
            train,
            mesh,
            eval: EvalConfig::default(),
            export: Default::default(),
        }
    }
}

/// `c` with `iterations` training steps and every step-indexed schedule at the same fraction of
/// the run: the cos-anneal end, the constant and warm-up phases of the learning rate, the
/// coarse-to-fine hash levels (`model.field.hash_grid.progressive`), every ramped loss weight
/// (e.g. [`delayed_curvature`]) and the occupancy grid's decay per update
/// ([`rescale_decay`]: the grid forgets as much over the scaled run). A step `x` of `c` maps to
/// `round(x · iterations / c.train.iterations)`, at most `iterations`; an update interval stays
/// ≥ 1. The one place that scales a run's length: the `quick` preset and the pareto and smoke
/// grids of `study` use it. The checkpoint interval is left as it is.
pub fn scale_run_length(c: &RunConfig, iterations: u64) -> RunConfig {
    let n = iterations.max(1);
    let k = n as f64 / c.train.iterations.max(1) as f64;
    let scale = |x: u64| ((x as f64 * k).round() as u64).min(n);
    let mut s = c.clone();
    s.train.iterations = n;
    s.model.render.cos_anneal_end = scale(c.model.render.cos_anneal_end);
    s.train.lr.constant_steps = scale(c.train.lr.constant_steps);
    s.train.lr.warmup_steps = scale(c.train.lr.warmup_steps);
    s.model.render.occupancy.ema_decay =
        rescale_decay(c.model.render.occupancy.ema_decay, c.train.iterations, n);
    if let Some(p) = &mut s.model.field.hash_grid.progressive {
        p.start_step = scale(p.start_step);
        p.update_steps = scale(p.update_steps).max(1);
    }
    for (_, w) in s.model.loss.weights_mut() {
        if let Scheduled::Linear(s0, a, b, s1) = *w {
            *w = Scheduled::Linear(scale(s0), a, b, scale(s1));
        }
    }
    s
}

/// The curvature weight of every preset: Neuralangelo's mean-|Laplacian| loss at
/// weight 5·10⁻⁴ (`projects/neuralangelo/configs/base.yaml`, `curvature: 5e-4`), but **off for the
/// first half of training** and ramped in linearly over the next tenth, i.e.
/// `[iterations/2, 0, 5e-4, 3·iterations/5]`: the ramp ends when the last hash level turns on in
/// every preset's progressive schedule (fast 1200/2000, default 4800/8000, paper 12000/20000).
/// Neuralangelo warms the weight up from step 0; on short runs that froze a membrane across a hole
/// before the masks could open it, while the delayed ramp lets the masks carve the topology first
/// and then smooths it (measured: docs/recipe.md).
pub fn delayed_curvature(iterations: u64) -> Scheduled {
    Scheduled::Linear(iterations / 2, 0.0, 5e-4, iterations * 3 / 5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::config::resolve;

    #[test]
    fn every_preset_delays_curvature_until_the_topology_has_formed() {
        for preset in [Preset::Quick, Preset::Fast, Preset::Default, Preset::Paper] {
            let c = preset.config();
            let n = c.train.iterations;
            let w = c.model.loss.curvature;
            assert_eq!(w.at(0), 0.0, "{preset:?}");
            assert_eq!(w.at(n / 2), 0.0, "{preset:?}");
            assert!((w.at(n) - 5e-4).abs() < 1e-12, "{preset:?}");
            assert!(
                w.at(n * 11 / 20) > 0.0 && w.at(n * 11 / 20) < 5e-4,
                "{preset:?}"
            );
            // The ramp ends when the last hash level is on, not before.
            let p = c.model.field.hash_grid.progressive.unwrap();
            let levels = c.model.field.hash_grid.n_levels;
            let all_on = p.start_step + (levels - p.start_level) as u64 * p.update_steps;
            assert_eq!(n * 3 / 5, all_on, "{preset:?}");
            w.check().unwrap();
        }
    }

    /// Every preset but `paper` (the reference) chooses its start by the hull's cover of the
    /// init sphere.
    #[test]
    fn presets_choose_sphere_or_hull_and_paper_keeps_the_sphere() {
        for preset in [Preset::Quick, Preset::Fast, Preset::Default] {
            assert_eq!(
                preset.config().train.init.kind,
                InitKind::SphereOrHull,
                "{preset:?}"
            );
        }
        assert_eq!(Preset::Paper.config().train.init.kind, InitKind::Sphere);
    }

    /// `fast` (and `quick`, its copy) decay the occupancy grid at the reference's pace per fraction
    /// of the run; `paper` is the reference itself; `default` keeps the reference decay until it
    /// is measured.
    #[test]
    fn short_presets_scale_the_occupancy_decay_to_their_length() {
        for preset in [Preset::Quick, Preset::Fast] {
            let c = preset.config();
            let d = c.model.render.occupancy.ema_decay;
            assert_eq!(d, decay_for_run(c.train.iterations), "{preset:?}");
            assert!(d < 0.7, "{preset:?}: {d}");
        }
        for preset in [Preset::Default, Preset::Paper] {
            let c = preset.config();
            assert_eq!(
                c.model.render.occupancy.ema_decay,
                crate::render::occupancy::REFERENCE_DECAY
            );
        }
        // The rays the grid saves turn into more rays rather than a smaller batch: `default` and
        // `paper` let the ray count grow to 32× its start, as the reference does
        // (`max_train_num_rays` 8192 against `train_num_rays` 256); the short presets, whose
        // scaled decay leaves 4–9 samples per ray on thin shapes, spend their whole budget
        // per step (`train_num_rays × num_samples_per_ray`) down to 4 samples per ray.
        for preset in [Preset::Default, Preset::Paper] {
            let r = preset.config().model.render;
            assert_eq!(r.max_train_num_rays, 32 * r.train_num_rays, "{preset:?}");
        }
        for preset in [Preset::Quick, Preset::Fast] {
            let r = preset.config().model.render;
            let budget = r.train_num_rays * r.num_samples_per_ray;
            assert!(r.max_train_num_rays * 4 >= budget, "{preset:?}: {r:?}");
            assert!(r.max_train_num_rays > 32 * r.train_num_rays, "{preset:?}");
        }
        assert_eq!(
            Preset::Paper.config().model.render.occupancy.ema_decay,
            decay_for_run(Preset::Paper.config().train.iterations)
        );
    }

    /// The depth prior's automatic switch (`train::depth_auto`) checks in every preset but
    /// `paper`, whose reference has no prior; no preset asks for the prior itself.
    #[test]
    fn the_depth_switch_is_on_in_every_preset_but_paper() {
        for p in [Preset::Quick, Preset::Fast, Preset::Default, Preset::Paper] {
            let c = p.config();
            assert_eq!(c.train.depth.auto.enabled, p != Preset::Paper, "{p:?}");
            assert_eq!(c.train.depth.weight, 0.0, "{p:?}");
            assert!(c.train.depth.invalid().is_none(), "{p:?}");
        }
        assert_eq!(
            Preset::Fast.config().train.depth.auto.check_step(2000),
            Some(200),
            "fast checks at its prior's start step"
        );
    }

    #[test]
    fn quick_is_fast_with_half_size_images_half_the_samples_and_uniform_rays() {
        let (q, f) = (Preset::Quick.config(), Preset::Fast.config());
        assert_eq!(q.preset, Preset::Quick);
        assert_eq!(
            q.model.render.num_samples_per_ray * 2,
            f.model.render.num_samples_per_ray
        );
        assert_eq!((q.data.downscale, q.data.render_downscale), (2, 1));
        // Held-out views at the same pixel size as fast's.
        assert_eq!(
            q.data.downscale * q.data.render_downscale,
            f.data.downscale * f.data.render_downscale
        );
        // Without fast's error map, closing and one-sided differences (quick was measured
        // without them).
        assert!(f.train.error_map.share > 0.0 && f.mesh.close_radius > 0);
        assert!(q.train.error_map.is_default() && q.mesh.close_radius == 0);
        assert_eq!(
            (
                f.model.render.fd_central_every,
                f.model.render.fd_one_sided_span
            ),
            (4, 2.0)
        );
        assert_eq!(
            (
                q.model.render.fd_central_every,
                q.model.render.fd_one_sided_span
            ),
            (1, 1.0)
        );
        // Everything else is fast's, shortened to QUICK_ITERATIONS steps.
        let short = scale_run_length(&f, QUICK_ITERATIONS);
        assert_eq!(q.train.iterations, QUICK_ITERATIONS);
        let mut back = q.clone();
        back.preset = Preset::Fast;
        back.model.render.num_samples_per_ray = f.model.render.num_samples_per_ray;
        back.data.downscale = f.data.downscale;
        back.data.render_downscale = f.data.render_downscale;
        back.train.error_map = f.train.error_map.clone();
        back.mesh.close_radius = f.mesh.close_radius;
        back.model.render.fd_central_every = f.model.render.fd_central_every;
        back.model.render.fd_one_sided_span = f.model.render.fd_one_sided_span;
        // The depth prior's automatic switch a quarter into the run, not a tenth.
        assert_eq!(q.train.depth.auto.at, 0.25);
        assert_eq!(q.train.depth.auto.check_step(q.train.iterations), Some(350));
        back.train.depth.auto.at = f.train.depth.auto.at;
        // The decay comes from the reference directly; the rescaled f32 may differ in its last bit.
        let (dq, ds) = (
            q.model.render.occupancy.ema_decay,
            short.model.render.occupancy.ema_decay,
        );
        assert!((dq - ds).abs() <= 2.0 * f32::EPSILON, "{dq} {ds}");
        back.model.render.occupancy.ema_decay = ds;
        assert_eq!(back, short);
    }

    /// Scaling a run to its own length changes nothing; scaling it keeps every schedule at its
    /// fraction of the run and the grid's total forgetting.
    #[test]
    fn scaling_the_run_length_keeps_every_schedule_at_its_fraction() {
        for p in [Preset::Quick, Preset::Fast, Preset::Default, Preset::Paper] {
            let c = p.config();
            assert_eq!(scale_run_length(&c, c.train.iterations), c, "{p:?}");
            for n in [1, 7, c.train.iterations / 3, c.train.iterations * 2] {
                let s = scale_run_length(&c, n);
                let k = n as f64 / c.train.iterations as f64;
                assert_eq!(s.train.iterations, n);
                let near = |a: u64, b: u64| {
                    let want = ((b as f64 * k).round() as u64).min(n);
                    assert_eq!(a, want, "{p:?} n={n}: {a} for {b}");
                };
                near(s.model.render.cos_anneal_end, c.model.render.cos_anneal_end);
                near(s.train.lr.constant_steps, c.train.lr.constant_steps);
                near(s.train.lr.warmup_steps, c.train.lr.warmup_steps);
                let (ps, pc) = (
                    s.model.field.hash_grid.progressive.clone().unwrap(),
                    c.model.field.hash_grid.progressive.clone().unwrap(),
                );
                near(ps.start_step, pc.start_step);
                assert!(ps.update_steps >= 1);
                if (pc.update_steps as f64 * k).round() >= 1.0 {
                    near(ps.update_steps, pc.update_steps);
                }
                for ((name, ws), (_, wc)) in s
                    .model
                    .loss
                    .weights()
                    .into_iter()
                    .zip(c.model.loss.weights())
                {
                    match (ws, wc) {
                        (Scheduled::Linear(a0, v0, v1, a1), Scheduled::Linear(b0, u0, u1, b1)) => {
                            near(a0, b0);
                            near(a1, b1);
                            assert_eq!((v0, v1), (u0, u1), "{name}");
                        }
                        (ws, wc) => assert_eq!(ws, wc, "{name}"),
                    }
                }
                // ln(decay) × updates is the same (relative 1e-5: the decay is an f32).
                let forget = |c: &RunConfig| {
                    c.train.iterations as f64 * (c.model.render.occupancy.ema_decay as f64).ln()
                };
                // (Only where the f32 decay has not underflowed: 0.95^(20000/7) has.)
                if s.model.render.occupancy.ema_decay > 1e-6 {
                    let (a, b) = (forget(&s), forget(&c));
                    assert!((a / b - 1.0).abs() < 1e-5, "{p:?} n={n}: {a} {b}");
                }
                // Nothing else moves.
                let mut back = s.clone();
                back.train = c.train.clone();
                back.model.render.cos_anneal_end = c.model.render.cos_anneal_end;
                back.model.render.occupancy.ema_decay = c.model.render.occupancy.ema_decay;
                back.model.field.hash_grid.progressive =
                    c.model.field.hash_grid.progressive.clone();
                back.model.loss = c.model.loss.clone();
                let mut c_train = c.train.clone();
                c_train.iterations = s.train.iterations;
                c_train.lr.constant_steps = s.train.lr.constant_steps;
                c_train.lr.warmup_steps = s.train.lr.warmup_steps;
                assert_eq!(s.train, c_train, "{p:?} n={n}");
                assert_eq!(back, c, "{p:?} n={n}");
            }
        }
    }

    #[test]
    fn presets_resolve_and_round_trip_through_toml() {
        for p in [Preset::Quick, Preset::Fast, Preset::Default, Preset::Paper] {
            let c = resolve(Some(p), None, &[]).unwrap();
            assert_eq!(c.preset, p);
            let back = RunConfig::from_saved_toml(&c.to_toml(), "test").unwrap();
            assert_eq!(back, c);
        }
        let paper = Preset::Paper.config();
        assert_eq!(paper.train.iterations, 20000);
        assert_eq!(paper.model.field.hash_grid.log2_hashmap_size, 19);
        assert_eq!(paper.model.render.num_samples_per_ray, 1024);
    }
}
