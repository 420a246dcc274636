//! The NeuS model's public API: shapes and flat parameters, the batched forward/backward of a
//! training step ([`NeusModel::forward_backward`]: marching, shard orchestration, reduction; the
//! per-chunk phases are in `step.rs`, the buffers in `workspace.rs`), and the inference entry
//! points (SDF of points, rendering rays, occupancy updates). The configuration is in
//! [`super::config`].
//!
//! Per sample (midpoint `x` of a marched interval), the SDF network is evaluated at `x` and at the
//! six taps `x ± ε·e_k` (clamped to the box; `ε` = one cell of the finest active level). The
//! central differences give the SDF gradient `g`, the normal `n = g/max(|g|, 1e-12)` and the
//! eikonal term `(|g| − 1)²`. With only first derivatives anywhere, every backward pass is first
//! order (instant-nsr-pl `grad_type: finite_difference`).
//!
//! Work is split into fixed chunks of whole rays (`chunk_samples`, 256 by default: a chunk's
//! buffers stay in the L2 cache), the chunks into `shards` contiguous groups run in parallel with
//! rayon; each shard accumulates gradients in its own buffer (shard 0 directly in the caller's),
//! and the buffers are summed in shard order. The bits of the result depend only on the inputs,
//! the seed and `shards`, never on thread scheduling. The shard buffers and scratch vectors are
//! kept inside the model between steps (a cache behind a mutex, see `WorkspaceCache`), so a step
//! allocates nothing of the parameter size.
//!
//! Hot paths (measured in `benches/field.rs`): the level-parallel finite-difference stencil of
//! the hash grid ([`crate::field::lanes`]) with software prefetching, register-blocked MLP
//! kernels ([`crate::field::dense`]) with fused activations, the SDF channel of the taps computed
//! in the hidden layer's epilogue. The large buffers should come from
//! [`crate::field::alloc::LargeAligned`] (cache-line alignment, huge pages).

use super::alpha::{inv_s_from_variance, neus_alpha};
use super::background::{background_color, BackgroundSamples, BackgroundScratch};
pub(super) use super::neus::RayResult;
pub use super::neus::{
    mark_ray_grad, ray_grad, BackwardOutput, ModelError, NeusModel, PhaseTimes, RayBatch,
    RayGradCell, RenderOutput, RAY_GRAD_SKIP,
};
use super::occupancy::OccupancyGrid;
use super::ray_loss::{BatchCounts, RayLoss};
use super::rays::{march_rays, RaySamples};
use super::schedule::Schedule;
use super::step::{StepCtx, Sums};
use super::workspace::{group, split, split_mut, Scratch, VARIANCE};
use crate::field::mlp::MlpTape;
use crate::field::Real;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use std::time::Instant;

impl NeusModel {
    /// Background samples of a batch (`None` without a learned background), jittered from their
    /// own stream of `jitter_seed` so the foreground's jitter is the same with or without them.
    fn sample_background(
        &self,
        b: &RayBatch,
        jitter_seed: Option<u64>,
    ) -> Option<BackgroundSamples> {
        let bg = self.background.as_ref()?;
        let mut rng = jitter_seed.map(|s| Pcg64Mcg::seed_from_u64(s ^ 0x6267_5f6a_6974_7465));
        Some(BackgroundSamples::new(
            b.origins,
            b.dirs,
            self.config.render.radius,
            bg.n_outside,
            rng.as_mut(),
        ))
    }

    fn sample(
        &self,
        b: &RayBatch,
        occ: Option<&OccupancyGrid>,
        jitter_seed: Option<u64>,
    ) -> RaySamples {
        let jitter: Vec<f32> = match jitter_seed {
            Some(seed) => {
                let mut rng = Pcg64Mcg::seed_from_u64(seed);
                (0..b.origins.len()).map(|_| rng.random::<f32>()).collect()
            }
            None => Vec::new(),
        };
        let occ = occ.filter(|_| self.config.render.occupancy.enabled);
        march_rays(
            b.origins,
            b.dirs,
            self.config.render.radius,
            self.render_step_size(),
            &jitter,
            occ,
        )
    }

    /// Fixed chunking: consecutive whole rays, at most `chunk_samples` samples per chunk (a longer
    /// ray gets a chunk of its own; background samples count too). Returns ray boundaries.
    fn chunks(&self, s: &RaySamples) -> Vec<usize> {
        let cap = self.config.render.chunk_samples;
        let n_bg = self.background.as_ref().map_or(0, |b| b.n_outside);
        let mut b = vec![0usize];
        let mut cur = 0usize;
        for r in 0..s.n_rays() {
            let m = s.range(r).len() + n_bg;
            if cur > 0 && cur + m > cap {
                b.push(r);
                cur = 0;
            }
            cur += m;
        }
        if *b.last().unwrap_or(&0) != s.n_rays() || s.n_rays() == 0 {
            b.push(s.n_rays());
        }
        b
    }

    /// One training step's forward and backward on a batch, with the loss `loss` (the trainer's
    /// is `train::loss`; see [`RayLoss`]).
    ///
    /// Accumulates (adds) `∂total/∂params` into `grads` (same layout as `params`), returns the
    /// loss's sums and the renderer's. `sched`: the cos anneal and active levels at this step
    /// (its loss weights are the loss's business). `step_seed` seeds the stratified jitter.
    /// `occ`: the occupancy grid (or `None` to march everything). Generic over [`Real`] so the
    /// gradient checks run it in `f64`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_backward<T: Real, L: RayLoss>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        loss: &L,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
    ) -> Result<BackwardOutput<L::Sums>, ModelError> {
        self.forward_backward_rays(params, grads, batch, loss, sched, occ, step_seed, None)
    }

    /// [`Self::forward_backward`], also writing each ray's `(∂L/∂o, ∂L/∂d)` into `ray_grads`
    /// (`[n]`, see [`RayGradCell`]) when given: the gradient through every point where the SDF
    /// network is evaluated (the sample and its finite-difference taps) and through the view
    /// direction's direct uses (the colour network's encoding and NeuS's `cos(d, n)`), with the
    /// sample distances `t` held fixed (as BARF does, Lin et al. 2021, §3). The learned
    /// background's samples are not differentiated. Pose refinement's input
    /// (`crate::train::pose`). Without `ray_grads` the bits are those of `forward_backward`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_backward_rays<T: Real, L: RayLoss>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        loss: &L,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
        ray_grads: Option<&[RayGradCell]>,
    ) -> Result<BackwardOutput<L::Sums>, ModelError> {
        self.check_params(params)?;
        self.check_params(grads)?;
        self.check_batch(batch)?;
        let n = batch.origins.len();
        loss.check(n)?;
        if let Some(g) = ray_grads.filter(|g| g.len() != n) {
            return Err(ModelError::Shape {
                what: "ray_grads",
                expected: n,
                got: g.len(),
            });
        }
        let t0 = Instant::now();
        let jitter = self.config.render.randomized.then_some(step_seed);
        let samples = self.sample(batch, occ, jitter);
        let bg_samples = self.sample_background(batch, jitter);
        let sample_time = t0.elapsed().as_secs_f64();
        // With a learned background every ray has samples (behind the box at least).
        let n_valid = if bg_samples.is_some() {
            n
        } else {
            (0..n).filter(|&r| !samples.range(r).is_empty()).count()
        };
        let counts = BatchCounts {
            n_rays: n,
            n_valid,
            n_samples: samples.n_samples(),
        };
        let pg = split(&self.layout, params);
        let (inv_s, d_inv_s_dv) = inv_s_from_variance(pg.var[0]);
        let ctx = StepCtx {
            batch,
            samples: &samples,
            bg_samples: bg_samples.as_ref(),
            sched,
            inv_s: inv_s.to_f64(),
            counts,
            ray_grads,
        };
        let bounds = self.chunks(&samples);
        let n_chunks = bounds.len() - 1;
        let k = self.n_shards().min(n_chunks).max(1);
        let mut ws = self.workspace.take::<T>();
        if ws.extra.len() < k - 1 {
            ws.extra.resize_with(k - 1, Vec::new);
        }
        for e in ws.extra.iter_mut() {
            if e.len() != params.len() {
                *e = vec![T::ZERO; params.len()];
            }
        }
        ws.scratch
            .resize_with(k.max(ws.scratch.len()), Scratch::default);
        let mut views: Vec<&mut [T]> = Vec::with_capacity(k);
        views.push(&mut *grads);
        for e in ws.extra.iter_mut().take(k - 1) {
            views.push(&mut e[..]);
        }
        let results: Vec<(Sums<L::Sums>, PhaseTimes)> = views
            .into_par_iter()
            .zip(ws.scratch[..k].par_iter_mut())
            .enumerate()
            .map(|(s, (g, scratch))| {
                let c0 = s * n_chunks / k;
                let c1 = (s + 1) * n_chunks / k;
                let mut sums = Sums::default();
                let mut times = PhaseTimes::default();
                let mut gg = split_mut(&self.layout, g);
                for c in c0..c1 {
                    self.train_chunk(
                        &pg,
                        &mut gg,
                        &ctx,
                        loss,
                        bounds[c],
                        bounds[c + 1],
                        scratch,
                        &mut sums,
                        &mut times,
                    );
                }
                (sums, times)
            })
            .collect();
        let t1 = Instant::now();
        let mut sums = Sums::<L::Sums>::default();
        let mut times = PhaseTimes {
            sample: sample_time,
            ..Default::default()
        };
        for (s, t) in &results {
            L::merge(&mut sums.loss, &s.loss);
            sums.eik += s.eik;
            sums.curv += s.curv;
            sums.d_inv_s += s.d_inv_s;
            times.add(t);
        }
        // Fixed-order reduction of the shard buffers, parallel over index blocks; the shard
        // buffers are zeroed on the way, ready for the next step.
        if k > 1 {
            const BLOCK: usize = 1 << 14;
            let mut extra: Vec<std::slice::ChunksMut<'_, T>> = ws
                .extra
                .iter_mut()
                .take(k - 1)
                .map(|e| e.chunks_mut(BLOCK))
                .collect();
            let blocks: Vec<(&mut [T], Vec<&mut [T]>)> = grads
                .chunks_mut(BLOCK)
                .map(|gb| {
                    (
                        gb,
                        extra
                            .iter_mut()
                            .map(|e| e.next().expect("same length"))
                            .collect(),
                    )
                })
                .collect();
            blocks.into_par_iter().for_each(|(gb, es)| {
                for e in es {
                    for (a, b) in gb.iter_mut().zip(e.iter_mut()) {
                        *a += *b;
                        *b = T::ZERO;
                    }
                }
            });
        }
        self.workspace.put(ws);
        // Variance gradient: the per-sample ∂α/∂inv_s summed in f64, chained through exp(10v).
        let var_off = group(&self.layout, VARIANCE).start;
        grads[var_off] += T::from_f64(sums.d_inv_s) * d_inv_s_dv;
        times.reduce = t1.elapsed().as_secs_f64();
        Ok(BackwardOutput {
            loss: sums.loss,
            eikonal_sum: sums.eik,
            curvature_sum: sums.curv,
            counts,
            inv_s: inv_s.to_f64(),
            times,
        })
    }

    /// Renders rays without gradients (held-out views) with the given schedule (normally
    /// [`ModelConfig::inference_schedule`]), no jitter, and the occupancy grid if given.
    pub fn render(
        &self,
        params: &[f32],
        batch: &RayBatch,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
    ) -> Result<RenderOutput, ModelError> {
        self.check_params(params)?;
        self.check_batch(batch)?;
        let n = batch.origins.len();
        let samples = self.sample(batch, occ, None);
        let bg_samples = self.sample_background(batch, None);
        let pg = split(&self.layout, params);
        let ctx = StepCtx {
            batch,
            samples: &samples,
            bg_samples: bg_samples.as_ref(),
            sched,
            inv_s: inv_s_from_variance(pg.var[0]).0 as f64,
            counts: BatchCounts::default(),
            ray_grads: None,
        };
        let bounds = self.chunks(&samples);
        let parts: Vec<Vec<RayResult>> = (0..bounds.len() - 1)
            .into_par_iter()
            // One scratch per rayon job split, reused across its chunks.
            .map_init(Scratch::default, |scratch, c| {
                let mut out = Vec::new();
                self.render_chunk(&pg, &ctx, bounds[c], bounds[c + 1], scratch, &mut out);
                out
            })
            .collect();
        let mut o = RenderOutput {
            rgb: vec![[0.0; 3]; n],
            opacity: vec![0.0; n],
            depth: vec![0.0; n],
            normal: vec![[0.0; 3]; n],
            n_samples: samples.n_samples(),
        };
        for (r, c, op, d, nr) in parts.into_iter().flatten() {
            o.rgb[r] = c;
            o.opacity[r] = op;
            o.depth[r] = d;
            o.normal[r] = nr;
        }
        Ok(o)
    }

    /// The learned background's colour `C_bg` of each ray (`[n][3]`, what the foreground is
    /// composited on; [`super::background`]), without jitter, with `render.background` behind
    /// it. An error without a learned background.
    pub fn render_background(
        &self,
        params: &[f32],
        batch: &RayBatch,
    ) -> Result<Vec<[f32; 3]>, ModelError> {
        self.check_params(params)?;
        self.check_batch(batch)?;
        let Some(field) = &self.background else {
            return Err(ModelError::Invalid {
                key: "model.background.kind",
                value: "\"none\"".into(),
                why: "there is no learned background to render",
            });
        };
        let s = self
            .sample_background(batch, None)
            .expect("a background field samples");
        let pg = split(&self.layout, params);
        let r = self.config.render.radius as f64;
        let behind = self.config.render.background;
        let k = field.n_outside;
        const RAYS: usize = 64;
        let n = batch.origins.len();
        let mut out = vec![[0f32; 3]; n];
        out.par_chunks_mut(RAYS).enumerate().for_each_init(
            BackgroundScratch::<f32>::default,
            |sc, (c, o)| {
                let r0 = c * RAYS;
                let (mut x, mut dirs) = (Vec::new(), Vec::new());
                for ray in r0..r0 + o.len() {
                    let (og, d) = (batch.origins[ray], batch.dirs[ray]);
                    for &t in &s.t[s.range(ray)] {
                        x.push([0, 1, 2].map(|a| og[a] as f64 + d[a] as f64 * t as f64));
                        dirs.push(d);
                    }
                }
                let span = r0 * k..(r0 + o.len()) * k;
                field.forward(pg.bg_density, pg.bg_color, &x, &dirs, &s.dt[span], r, sc);
                for (i, c) in o.iter_mut().enumerate() {
                    let rg = i * k..(i + 1) * k;
                    *c = background_color(&sc.alpha[rg.clone()], &sc.rgb[rg], behind);
                }
            },
        );
        Ok(out)
    }

    /// SDF (channel 0 of the SDF network) at points `[n][3]` of the normalised space, with
    /// `active` hash-grid levels. Parallel over fixed chunks; usable as a marching-cubes closure:
    /// `|pts: &[[f32; 3]]| model.sdf(&params, pts, active)`.
    pub fn sdf(&self, params: &[f32], points: &[[f32; 3]], active: usize) -> Vec<f32> {
        let pg = split(&self.layout, params);
        let d = self.grid.output_dim();
        let r = self.config.render.radius;
        let mut out = vec![0f32; points.len()];
        const CH: usize = 1024;
        out.par_chunks_mut(CH)
            .zip(points.par_chunks(CH))
            .for_each_init(
                || (Vec::new(), MlpTape::default()),
                |(enc, tape), (o, pts)| {
                    let n = pts.len();
                    enc.resize(n * d, 0f32);
                    self.grid.encode_batch(pg.hash, pts, r, active, enc, d);
                    // The SDF channel straight from the hidden layer's epilogue.
                    self.sdf_mlp
                        .forward_hidden_with(pg.sdf, &enc[..n * d], n, tape, |i, h| {
                            o[i] = self.sdf_mlp.output_channel(pg.sdf, 0, h);
                        });
                },
            );
        out
    }

    /// Occupancy-grid update at training step `step` (see [`crate::render::occupancy`] for the
    /// rule). Evaluates the SDF at the planned points and turns it into the NeuS alpha of one
    /// render step with `cos = −1`, through the one alpha function. Returns whether it updated.
    pub fn update_occupancy(
        &self,
        params: &[f32],
        grid: &mut OccupancyGrid,
        step: u64,
        sched: Schedule,
        seed: u64,
    ) -> bool {
        let cfg = &self.config.render.occupancy;
        let Some((cells, pts)) = grid.plan_update(cfg, step, seed) else {
            return false;
        };
        let sdf = self.sdf(params, &pts, sched.active_levels);
        let inv_s = self.inv_s(params);
        let dt = self.render_step_size();
        let alpha: Vec<f32> = sdf
            .iter()
            .map(|&f| neus_alpha::<f32, false>(f, -1.0, dt, inv_s, 1.0).0)
            .collect();
        grid.apply_update(cfg, &cells, &alpha);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::ModelConfig;

    #[test]
    fn layout_and_defaults() {
        let m = NeusModel::new(ModelConfig::default()).unwrap();
        let names: Vec<&str> = m.layout.groups.iter().map(|g| g.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "hash_grid",
                "sdf_mlp",
                "color_mlp",
                "variance",
                "appearance"
            ]
        );
        assert_eq!(m.sdf_mlp.dims, [35, 64, 13]);
        assert_eq!(m.color_mlp.dims, [13 + 16 + 3, 64, 64, 3]);
        let p = m.init_params(1);
        assert_eq!(p, m.init_params(1), "seeded");
        assert!((m.inv_s(&p) - 3f32.exp()).abs() < 1e-4);
        assert_eq!(m.layout.group("variance").unwrap().lr_scale, 0.1);
        let mut c = ModelConfig::default();
        c.field.appearance = crate::field::config::AppearanceConfig {
            n_codes: 6,
            code_dim: 4,
            with_scalar: true,
        };
        let m = NeusModel::new(c).unwrap();
        assert_eq!(m.color_mlp.dims[0], 13 + 16 + 3 + 4 + 1);
        let g = m.layout.group("appearance").unwrap();
        assert_eq!(g.shape, [6, 4]);
        assert!(
            m.init_params(2)[g.range()].iter().all(|&v| v == 0.0),
            "appearance starts at zero"
        );
        let mut bad = ModelConfig::default();
        bad.field.appearance.with_scalar = true;
        assert!(NeusModel::new(bad)
            .unwrap_err()
            .to_string()
            .contains("with_scalar"));
    }

    /// `sdf` (batched level-parallel encoding, register-kernel MLP, fused output channel)
    /// against a slow f64 reference (naive encoding, naive layers, standard-library softplus)
    /// on the default network with perturbed weights, inside and on the box.
    #[test]
    fn sdf_matches_slow_reference() {
        use crate::field::fastmath::softplus_f64;
        use crate::field::mlp::linear_forward_naive;
        use rand::Rng;
        let model = NeusModel::new(ModelConfig::default()).unwrap();
        let mut p = model.init_params(3);
        let mut rng = Pcg64Mcg::seed_from_u64(4);
        for i in model.layout.group("hash_grid").unwrap().range() {
            p[i] = rng.random_range(-0.05..0.05);
        }
        for i in model.layout.group("sdf_mlp").unwrap().range() {
            p[i] += rng.random_range(-0.05..0.05);
        }
        let mut pts: Vec<[f32; 3]> = (0..300)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        pts.push([1.0, -1.0, 1.0]);
        let active = 13;
        let got = model.sdf(&p, &pts, active);
        let p64: Vec<f64> = p.iter().map(|&v| v as f64).collect();
        let hash = &p64[model.layout.group("hash_grid").unwrap().range()];
        let sdf = &p64[model.layout.group("sdf_mlp").unwrap().range()];
        let dims = &model.sdf_mlp.dims;
        let (d0, d1) = (dims[0], dims[1]);
        let mut worst = 0.0f64;
        for (x, g) in pts.iter().zip(&got) {
            let enc = model
                .grid
                .encode_naive(hash, x.map(|v| v as f64), 1.0, active);
            let mut h = vec![0.0; d1];
            linear_forward_naive(&sdf[..d0 * d1], &sdf[d0 * d1..], &enc, 1, d0, d1, &mut h);
            for v in h.iter_mut() {
                *v = softplus_f64(*v, 100.0).0;
            }
            let o = d1 * (d0 + 1);
            let mut y = [0.0];
            linear_forward_naive(&sdf[o..], &sdf[o + dims[2] * d1..], &h, 1, d1, 1, &mut y);
            worst = worst.max((*g as f64 - y[0]).abs() / (1.0 + y[0].abs()));
        }
        assert!(worst < 1e-5, "sdf vs slow reference: {worst}");
    }
}
