//! The forward (and, when training, backward) of one chunk of whole rays, one function per phase.
//! The phases and their [`PhaseTimes`] fields:
//!
//! | phase | function | time |
//! |---|---|---|
//! | positions, taps, hash encoding | [`NeusModel::encode_forward`] | `encode_fwd` |
//! | SDF network on centres and taps | [`NeusModel::sdf_forward`] | `sdf_mlp_fwd` |
//! | gradients, normals, colour grid, colour network | [`NeusModel::color_forward`] | `color_fwd` |
//! | alpha, compositing (+ loss, compositing backward) | [`NeusModel::alpha_forward`], [`NeusModel::composite_render`] / [`NeusModel::composite_loss_backward`] | `render` |
//! | colour network backward (and the colour grid's) | [`NeusModel::color_backward`] | `color_bwd` |
//! | alpha / normal / eikonal / curvature backward, SDF network backward | [`NeusModel::geometry_backward`], [`NeusModel::sdf_backward`] | `sdf_mlp_bwd` |
//! | hash grid backward | [`NeusModel::encode_backward`] | `encode_bwd` |
//!
//! Each phase reads and writes the chunk's [`Scratch`] buffers (shapes documented there). The
//! functions are private to the renderer; [`NeusModel::train_chunk`] and
//! [`NeusModel::render_chunk`] run them in order.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::alpha::{neus_alpha, AlphaGrad};
use super::background::{
    composite_two_backward, composite_two_forward, BackgroundSamples, Layer, RayGrad,
};
use super::composite::{composite_backward, composite_forward};
use super::neus::NeusModel;
use super::neus::{PhaseTimes, RayBatch, RayResult};
use super::ray_loss::{BatchCounts, RayLoss};
use super::rays::RaySamples;
use super::schedule::Schedule;
use super::workspace::{tap_rows, Groups, GroupsMut, Scratch};
use crate::field::config::AppearanceConfig;
use crate::field::hashgrid::Sides;
use crate::field::sh::{sh4, SH_DIM};
use crate::field::{sigmoid, Real};
use std::time::Instant;

mod rays;

/// What every chunk of one batch shares.
pub(super) struct StepCtx<'a> {
    pub(super) batch: &'a RayBatch<'a>,
    pub(super) samples: &'a RaySamples,
    /// The learned background's samples (`None` without one).
    pub(super) bg_samples: Option<&'a BackgroundSamples>,
    pub(super) sched: Schedule,
    pub(super) inv_s: f64,
    pub(super) counts: BatchCounts,
    /// Where each ray's `(∂L/∂o, ∂L/∂d)` goes ([`NeusModel::ray_backward`]), `None`: nowhere.
    pub(super) ray_grads: Option<&'a [super::neus::RayGradCell]>,
}

/// Sums of a shard: the loss's own terms and the per-sample ones the renderer computes.
#[derive(Default, Clone, Copy)]
pub(super) struct Sums<S> {
    /// The loss's per-ray terms ([`RayLoss::Sums`]).
    pub(super) loss: S,
    /// `Σ (|∇f| − 1)²` over samples.
    pub(super) eik: f64,
    /// `Σ |Δf|` over samples (only when the curvature weight is > 0).
    pub(super) curv: f64,
    /// `Σ ∂L/∂inv_s` over samples.
    pub(super) d_inv_s: f64,
}

/// Sizes and constants of one chunk of rays `r0..r1` (samples `s0..s0 + n`).
struct Chunk<'a, T> {
    r0: usize,
    r1: usize,
    /// First sample of the chunk in the batch.
    s0: usize,
    /// Samples in the chunk.
    n: usize,
    /// SDF network outputs (SDF + feature).
    fdim: usize,
    /// Encoding width.
    d: usize,
    /// Last hidden width of the SDF network.
    wh: usize,
    /// Colour network input width.
    dc: usize,
    app: &'a AppearanceConfig,
    radius: T,
    active: usize,
    /// Finite-difference step `ε` of a central difference (normalised units).
    eps: T,
    /// One-sided step `span·ε` (`RenderConfig::fd_one_sided_span`) and its inverse.
    eps1: T,
    inv_eps1: T,
    /// `1/(2ε)`, a central difference's divisor.
    inv_2eps: T,
    /// Which samples take central differences: 1 = all, 0 = none (one-sided differences), `k` =
    /// those whose index in the batch is a multiple of `k` ([`NeusModel::central_every`]).
    central_every: usize,
    inv_s: T,
    anneal: T,
    bg: [T; 3],
}

impl<T: Real> Chunk<'_, T> {
    /// The factor of a one-sided difference `f(x ± ε·e_a) − f(x)`: `+1/ε` or `−1/ε`.
    #[inline(always)]
    fn one_sided_scale(&self, side: Sides) -> T {
        if side == Sides::Minus {
            -self.inv_eps1
        } else {
            self.inv_eps1
        }
    }
}

impl NeusModel {
    /// Which samples of a step take central differences (see [`Chunk::central_every`]):
    /// `render.fd_central_every = 1` gives all; `k > 1` gives every `k`-th while the curvature
    /// loss is on (`curvature`), none otherwise.
    fn central_every(&self, curvature: bool) -> usize {
        match self.config.render.fd_central_every as usize {
            0 | 1 => 1,
            k if curvature => k,
            _ => 0,
        }
    }

    fn chunk_consts<T: Real>(
        &self,
        ctx: &StepCtx,
        r0: usize,
        r1: usize,
        central_every: usize,
    ) -> Chunk<'_, T> {
        let samples = ctx.samples;
        let s0 = samples.ray_start[r0];
        let s1 = samples.ray_start[r1];
        let cfgf = &self.config.field;
        let active = ctx.sched.active_levels;
        let eps = T::from_f64(self.fd_eps(active));
        let eps1 = eps * T::from_f32(self.config.render.fd_one_sided_span);
        Chunk {
            r0,
            r1,
            s0,
            n: s1 - s0,
            fdim: cfgf.sdf.feature_dim,
            d: self.grid.output_dim(),
            wh: self.sdf_mlp.last_hidden_dim(),
            dc: cfgf.color_input_dim(),
            app: &cfgf.appearance,
            radius: T::from_f32(self.config.render.radius),
            active,
            eps,
            eps1,
            inv_eps1: T::ONE / eps1,
            inv_2eps: T::ONE / (eps + eps),
            central_every,
            inv_s: T::from_f64(ctx.inv_s),
            anneal: T::from_f32(ctx.sched.cos_anneal),
            bg: self.config.render.background.map(T::from_f32),
        }
    }

    /// The forward and backward of chunk `r0..r1` of a training step: adds the parameter
    /// gradients into `g`, the sums into `sums`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn train_chunk<T: Real, L: RayLoss>(
        &self,
        p: &Groups<T>,
        g: &mut GroupsMut<T>,
        ctx: &StepCtx,
        loss: &L,
        r0: usize,
        r1: usize,
        sc: &mut Scratch<T>,
        sums: &mut Sums<L::Sums>,
        times: &mut PhaseTimes,
    ) {
        let curvature = loss.sample_weights(&ctx.counts).curvature > 0.0;
        let c = self.chunk_consts::<T>(ctx, r0, r1, self.central_every(curvature));
        self.forward(p, ctx, &c, sc, times);
        let t_bg = Instant::now();
        self.background_forward(p, ctx, &c, sc);
        times.background += t_bg.elapsed().as_secs_f64();

        let t_r = Instant::now();
        self.alpha_forward::<T, true>(ctx, &c, sc);
        self.composite_loss_backward(ctx, loss, &c, sc, &mut sums.loss);
        times.render += t_r.elapsed().as_secs_f64();

        let t_cb = Instant::now();
        self.color_backward(p, g, &c, sc);
        times.color_bwd += t_cb.elapsed().as_secs_f64();

        let t_sb = Instant::now();
        self.geometry_backward(g, ctx, loss, &c, sc, sums);
        self.sdf_backward(p, g, &c, sc, ctx.ray_grads.is_some());
        times.sdf_mlp_bwd += t_sb.elapsed().as_secs_f64();

        let t_rb = Instant::now();
        self.ray_backward(p, ctx, &c, sc);
        times.encode_bwd += t_rb.elapsed().as_secs_f64();

        let t_eb = Instant::now();
        self.encode_backward(g, &c, sc);
        times.encode_bwd += t_eb.elapsed().as_secs_f64();

        if let Some(field) = &self.background {
            let t_bg = Instant::now();
            field.backward(
                p.bg_density,
                p.bg_color,
                g.bg_density,
                g.bg_color,
                &mut sc.bg,
            );
            times.background += t_bg.elapsed().as_secs_f64();
        }
    }

    /// The forward of chunk `r0..r1` without gradients: one [`RayResult`] per ray into `out`.
    pub(super) fn render_chunk(
        &self,
        p: &Groups<f32>,
        ctx: &StepCtx,
        r0: usize,
        r1: usize,
        sc: &mut Scratch<f32>,
        out: &mut Vec<RayResult>,
    ) {
        // Central differences on every sample: renders and their normals do not depend on the
        // training's tap layout.
        let c = self.chunk_consts::<f32>(ctx, r0, r1, 1);
        let mut times = PhaseTimes::default();
        self.forward(p, ctx, &c, sc, &mut times);
        self.background_forward(p, ctx, &c, sc);
        self.alpha_forward::<f32, false>(ctx, &c, sc);
        self.composite_render(ctx, &c, sc, out);
    }

    /// The learned background on the chunk's rays (nothing without one): positions, directions
    /// and intervals of its samples (`bg_x`, `bg_dirs`, `bg_t`, `bg_dt`), then the field's
    /// forward into `sc.bg` ([`super::background::BackgroundField::forward`]).
    fn background_forward<T: Real>(
        &self,
        p: &Groups<T>,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
    ) {
        let (Some(field), Some(bs)) = (&self.background, ctx.bg_samples) else {
            return;
        };
        sc.bg_x.clear();
        sc.bg_dirs.clear();
        sc.bg_t.clear();
        sc.bg_dt.clear();
        for r in c.r0..c.r1 {
            let o = ctx.batch.origins[r];
            let d = ctx.batch.dirs[r];
            for s in bs.range(r) {
                let t = bs.t[s] as f64;
                sc.bg_x
                    .push([0, 1, 2].map(|a| o[a] as f64 + d[a] as f64 * t));
                sc.bg_dirs.push(d.map(T::from_f32));
                sc.bg_t.push(T::from_f32(bs.t[s]));
                sc.bg_dt.push(T::from_f32(bs.dt[s]));
            }
        }
        field.forward(
            p.bg_density,
            p.bg_color,
            &sc.bg_x,
            &sc.bg_dirs,
            &sc.bg_dt,
            self.config.render.radius as f64,
            &mut sc.bg,
        );
    }

    /// The phases up to the colour of each sample, timed.
    fn forward<T: Real>(
        &self,
        p: &Groups<T>,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
        times: &mut PhaseTimes,
    ) {
        let t_enc = Instant::now();
        self.encode_forward(p, ctx, c, sc);
        times.encode_fwd += t_enc.elapsed().as_secs_f64();

        let t_mlp = Instant::now();
        self.sdf_forward(p, c, sc);
        times.sdf_mlp_fwd += t_mlp.elapsed().as_secs_f64();

        let t_col = Instant::now();
        self.color_forward(p, ctx, c, sc);
        times.color_fwd += t_col.elapsed().as_secs_f64();
    }

    /// Positions, taps and their hash encodings: `points`, `tap_points`, `tap_off`, `dirs`,
    /// `ray_t`, `encoding`.
    #[inline]
    fn encode_forward<T: Real>(
        &self,
        p: &Groups<T>,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
    ) {
        let samples = ctx.samples;
        let (n, d, eps, radius) = (c.n, c.d, c.eps, c.radius);
        sc.points.clear();
        sc.tap_points.clear();
        sc.tap_off.clear();
        sc.tap_off.push(0);
        sc.tap_sides.clear();
        sc.dirs.clear();
        sc.ray_t.clear();
        let mut m = 0;
        for r in c.r0..c.r1 {
            let o = ctx.batch.origins[r].map(T::from_f32);
            let dir = ctx.batch.dirs[r].map(T::from_f32);
            for s in samples.range(r) {
                let t = T::from_f32(samples.t[s]);
                let x = [o[0] + dir[0] * t, o[1] + dir[1] * t, o[2] + dir[2] * t];
                // One-sided samples alternate + and − (in runs of `k` between central ones), so
                // the differences' first-order errors cancel on average.
                let sides = match c.central_every {
                    1 => Sides::Both,
                    0 if s % 2 == 0 => Sides::Plus,
                    0 => Sides::Minus,
                    k if s % k == 0 => Sides::Both,
                    k if (s / k) % 2 == 0 => Sides::Plus,
                    _ => Sides::Minus,
                };
                // Taps x ± h·e_a (h = ε central, span·ε one-sided), clamped to the box; an unused
                // side's taps are the centre (they stay in the centre's cell, and the stencil
                // skips them).
                let used = sides.slots();
                let h = if sides == Sides::Both { eps } else { c.eps1 };
                let taps = [0, 1, 2].map(|a| {
                    let tap = |p: usize, v: T| if used.contains(&p) { v } else { x[a] };
                    [
                        tap(0, (x[a] + h).maxv(-radius).minv(radius)),
                        tap(1, (x[a] - h).maxv(-radius).minv(radius)),
                    ]
                });
                m += if sides == Sides::Both { 6 } else { 3 };
                sc.points.push(x);
                sc.tap_points.push(taps);
                sc.tap_off.push(m);
                sc.tap_sides.push(sides);
                sc.dirs.push(dir);
                sc.ray_t.push(t);
            }
        }
        sc.encoding.resize((n + m + 1) * d, T::ZERO);
        let (off, sides) = (&sc.tap_off, &sc.tap_sides);
        self.grid.encode_fd_batch(
            p.hash,
            &sc.points,
            &sc.tap_points,
            radius,
            c.active,
            &mut sc.encoding,
            |i| tap_rows(i, n, d, off, sides),
        );
    }

    /// The SDF network on centres and taps: `sdf_feature` (all outputs at the centres) and
    /// `tap_sdf` (the SDF channel at the taps), activations in `sdf_tape`.
    #[inline]
    fn sdf_forward<T: Real>(&self, p: &Groups<T>, c: &Chunk<T>, sc: &mut Scratch<T>) {
        let (n, fdim, wh) = (c.n, c.fdim, c.wh);
        let m = sc.tap_off[n];
        sc.sdf_feature.resize(n * fdim, T::ZERO);
        sc.tap_sdf.resize(m, T::ZERO);
        {
            // Taps need only the SDF channel: computed in the hidden layer's epilogue.
            let tap_sdf = &mut sc.tap_sdf;
            self.sdf_mlp.forward_hidden_with(
                p.sdf,
                &sc.encoding,
                n + m,
                &mut sc.sdf_tape,
                |i, h| {
                    if i >= n {
                        tap_sdf[i - n] = self.sdf_mlp.output_channel(p.sdf, 0, h);
                    }
                },
            );
        }
        let h = sc.sdf_tape.acts.last().expect("hidden layer");
        self.sdf_mlp
            .forward_last(p.sdf, &h[..n * wh], n, fdim, &mut sc.sdf_feature);
    }

    /// Gradients and normals from the taps (`sdf_grad`, `normal`), the colour network's input
    /// rows (`color_in`) and its output (`color_logits`, `rgb`).
    #[inline]
    fn color_forward<T: Real>(
        &self,
        p: &Groups<T>,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
    ) {
        let samples = ctx.samples;
        let (n, fdim, dc, app) = (c.n, c.fdim, c.dc, c.app);
        let inv_2eps = c.inv_2eps;
        let view = T::from_f32(ctx.sched.view_dependence);
        sc.sdf_grad.resize(n, [T::ZERO; 3]);
        sc.normal.resize(n, [T::ZERO; 3]);
        sc.color_in.resize(n * dc, T::ZERO);
        let mut i = 0;
        for r in c.r0..c.r1 {
            let code = if app.n_codes > 0 {
                ctx.batch.codes.get(r).copied().unwrap_or(0) as usize
            } else {
                0
            };
            let pr = T::from_f32(ctx.batch.p.get(r).copied().unwrap_or(0.0));
            for _ in samples.range(r) {
                let tp = &sc.tap_sdf[sc.tap_off[i]..sc.tap_off[i + 1]];
                let gr = if tp.len() == 6 {
                    [
                        (tp[0] - tp[1]) * inv_2eps,
                        (tp[2] - tp[3]) * inv_2eps,
                        (tp[4] - tp[5]) * inv_2eps,
                    ]
                } else {
                    // One-sided: ±(f(x ± ε·e_a) − f(x)) / ε.
                    let f = sc.sdf_feature[i * fdim];
                    let sgn = c.one_sided_scale(sc.tap_sides[i]);
                    [(tp[0] - f) * sgn, (tp[1] - f) * sgn, (tp[2] - f) * sgn]
                };
                let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
                let l = len.maxv(T::from_f64(1e-12));
                let nr = [gr[0] / l, gr[1] / l, gr[2] / l];
                sc.sdf_grad[i] = gr;
                sc.normal[i] = nr;
                let row = &mut sc.color_in[i * dc..(i + 1) * dc];
                row[..fdim].copy_from_slice(&sc.sdf_feature[i * fdim..(i + 1) * fdim]);
                sh4(sc.dirs[i], &mut row[fdim..fdim + SH_DIM]);
                if view != T::ONE {
                    // Degrees 1–3 only: the degree-0 term is a constant.
                    for v in &mut row[fdim + 1..fdim + SH_DIM] {
                        *v *= view;
                    }
                }
                row[fdim + SH_DIM..fdim + SH_DIM + 3].copy_from_slice(&nr);
                if app.n_codes > 0 {
                    let a0 = fdim + SH_DIM + 3;
                    row[a0..a0 + app.code_dim]
                        .copy_from_slice(&p.app[code * app.code_dim..(code + 1) * app.code_dim]);
                    if app.with_scalar {
                        row[a0 + app.code_dim] = pr;
                    }
                }
                i += 1;
            }
        }
        self.color_mlp
            .forward_hidden(p.color, &sc.color_in, n, &mut sc.color_tape);
        sc.color_logits.resize(n * 3, T::ZERO);
        let hc = sc.color_tape.acts.last().expect("hidden layer");
        self.color_mlp
            .forward_last(p.color, hc, n, 3, &mut sc.color_logits);
        sc.rgb.resize(n, [T::ZERO; 3]);
        for i in 0..n {
            for k in 0..3 {
                sc.rgb[i][k] = sigmoid(sc.color_logits[3 * i + k]);
            }
        }
    }

    /// The NeuS alpha of each sample (`alpha`) and, when `TRAIN`, its partials (`alpha_grad`).
    #[inline]
    fn alpha_forward<T: Real, const TRAIN: bool>(
        &self,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
    ) {
        let n = c.n;
        sc.alpha.resize(n, T::ZERO);
        sc.alpha_grad.resize(n, AlphaGrad::default());
        for i in 0..n {
            let nr = sc.normal[i];
            let dir = sc.dirs[i];
            let cos = dir[0] * nr[0] + dir[1] * nr[1] + dir[2] * nr[2];
            let dt = T::from_f32(ctx.samples.dt[c.s0 + i]);
            let (a, ag) =
                neus_alpha::<T, TRAIN>(sc.sdf_feature[i * c.fdim], cos, dt, c.inv_s, c.anneal);
            sc.alpha[i] = a;
            sc.alpha_grad[i] = ag;
        }
    }

    /// Composites each ray of the chunk on the render background into `out`.
    fn composite_render(
        &self,
        ctx: &StepCtx,
        c: &Chunk<f32>,
        sc: &Scratch<f32>,
        out: &mut Vec<RayResult>,
    ) {
        let k = ctx.bg_samples.map_or(0, |b| b.n_outside);
        for r in c.r0..c.r1 {
            let rg = ctx.samples.range(r);
            let (a, b) = (rg.start - c.s0, rg.end - c.s0);
            let o = if ctx.bg_samples.is_some() {
                let (ba, bb) = ((r - c.r0) * k, (r - c.r0 + 1) * k);
                let fg = Layer {
                    alpha: &sc.alpha[a..b],
                    rgb: &sc.rgb[a..b],
                    t: &sc.ray_t[a..b],
                };
                let bgl = Layer {
                    alpha: &sc.bg.alpha[ba..bb],
                    rgb: &sc.bg.rgb[ba..bb],
                    t: &sc.bg_t[ba..bb],
                };
                composite_two_forward(fg, &sc.normal[a..b], bgl, c.bg).0
            } else {
                composite_forward(
                    &sc.alpha[a..b],
                    &sc.rgb[a..b],
                    &sc.ray_t[a..b],
                    &sc.normal[a..b],
                    c.bg,
                )
            };
            out.push((
                r,
                o.rgb.map(|v| v.to_f32()),
                o.opacity.to_f32(),
                o.depth.to_f32(),
                o.normal.map(|v| v.to_f32()),
            ));
        }
    }

    /// Composites each ray, takes its loss and gradient from `loss`, and back-propagates through
    /// compositing into `d_alpha` and `d_rgb`.
    #[inline]
    fn composite_loss_backward<T: Real, L: RayLoss>(
        &self,
        ctx: &StepCtx,
        loss: &L,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
        sums: &mut L::Sums,
    ) {
        let n = c.n;
        sc.d_alpha.resize(n, T::ZERO);
        sc.d_rgb.resize(n, [T::ZERO; 3]);
        let bgt = loss
            .background(self.config.render.background)
            .map(T::from_f32);
        if let Some(bs) = ctx.bg_samples {
            let k = bs.n_outside;
            let nb = (c.r1 - c.r0) * k;
            sc.bg.d_alpha.resize(nb, T::ZERO);
            sc.bg.d_rgb.resize(nb, [T::ZERO; 3]);
            for r in c.r0..c.r1 {
                let rg = ctx.samples.range(r);
                let (a, b) = (rg.start - c.s0, rg.end - c.s0);
                let (ba, bb) = ((r - c.r0) * k, (r - c.r0 + 1) * k);
                let fg = Layer {
                    alpha: &sc.alpha[a..b],
                    rgb: &sc.rgb[a..b],
                    t: &sc.ray_t[a..b],
                };
                let bgl = Layer {
                    alpha: &sc.bg.alpha[ba..bb],
                    rgb: &sc.bg.rgb[ba..bb],
                    t: &sc.bg_t[ba..bb],
                };
                let (o, c_bg) = composite_two_forward(fg, &sc.normal[a..b], bgl, bgt);
                // Every ray has background samples: all rays are valid.
                let (g_rgb, g_op) = loss.ray(
                    &ctx.counts,
                    r,
                    o.rgb.map(|v| v.to_f64()),
                    o.opacity.to_f64(),
                    true,
                    sums,
                );
                composite_two_backward(
                    fg,
                    bgl,
                    bgt,
                    c_bg,
                    o.opacity,
                    RayGrad {
                        rgb: g_rgb.map(T::from_f64),
                        opacity: T::from_f64(g_op),
                        depth: T::ZERO,
                    },
                    &mut sc.d_alpha[a..b],
                    &mut sc.d_rgb[a..b],
                    &mut sc.bg.d_alpha[ba..bb],
                    &mut sc.bg.d_rgb[ba..bb],
                );
            }
            return;
        }
        for r in c.r0..c.r1 {
            let rg = ctx.samples.range(r);
            let (a, b) = (rg.start - c.s0, rg.end - c.s0);
            let o = composite_forward(
                &sc.alpha[a..b],
                &sc.rgb[a..b],
                &sc.ray_t[a..b],
                &sc.normal[a..b],
                bgt,
            );
            let (g_rgb, g_op) = loss.ray(
                &ctx.counts,
                r,
                o.rgb.map(|v| v.to_f64()),
                o.opacity.to_f64(),
                b > a,
                sums,
            );
            composite_backward(
                &sc.alpha[a..b],
                &sc.rgb[a..b],
                &sc.ray_t[a..b],
                bgt,
                g_rgb.map(T::from_f64),
                T::from_f64(g_op),
                T::ZERO,
                &mut sc.d_alpha[a..b],
                &mut sc.d_rgb[a..b],
            );
        }
    }

    /// The colour network's backward: parameter gradients into `g.color`, `d_color_in`.
    #[inline]
    fn color_backward<T: Real>(
        &self,
        p: &Groups<T>,
        g: &mut GroupsMut<T>,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
    ) {
        let (n, dc) = (c.n, c.dc);
        sc.d_color_logits.resize(n * 3, T::ZERO);
        for i in 0..n {
            for k in 0..3 {
                let y = sc.rgb[i][k];
                sc.d_color_logits[3 * i + k] = sc.d_rgb[i][k] * y * (T::ONE - y);
            }
        }
        let wc = self.color_mlp.last_hidden_dim();
        sc.d_color_hidden.resize(n * wc, T::ZERO);
        sc.d_color_in.resize(n * dc, T::ZERO);
        {
            let hc = sc.color_tape.acts.last().expect("hidden layer");
            self.color_mlp.backward_last(
                p.color,
                g.color,
                hc,
                n,
                3,
                &sc.d_color_logits,
                &mut sc.d_color_hidden,
            );
        }
        self.color_mlp.backward_hidden(
            p.color,
            g.color,
            &sc.color_in,
            n,
            &sc.color_tape,
            &mut sc.d_color_hidden,
            &mut sc.mlp_work,
            Some(&mut sc.d_color_in),
        );
    }

    /// Alpha, normal, eikonal and curvature backward to the SDF outputs (`d_sdf_feature`) and
    /// the taps (`d_tap_sdf`); appearance-code gradients into `g.app`; the eikonal, curvature and
    /// `∂L/∂inv_s` sums into `sums`.
    #[inline]
    fn geometry_backward<T: Real, L: RayLoss>(
        &self,
        g: &mut GroupsMut<T>,
        ctx: &StepCtx,
        loss: &L,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
        sums: &mut Sums<L::Sums>,
    ) {
        let (n, fdim, dc, app, eps) = (c.n, c.fdim, c.dc, c.app, c.eps);
        let inv_2eps = c.inv_2eps;
        sc.d_sdf_feature.resize(n * fdim, T::ZERO);
        sc.d_tap_sdf.resize(sc.tap_off[n], T::ZERO);
        let w = loss.sample_weights(&ctx.counts);
        let c_eik = T::from_f64(w.eikonal);
        let inv_eps2 = T::ONE / (eps * eps);
        // Only every `k`-th sample carries the curvature term when the others take forward
        // differences: weighted `k`, its sum estimates the sum over all samples.
        let k_curv = c.central_every.max(1) as f64;
        let c_curv = T::from_f64(w.curvature * k_curv) * inv_eps2;
        let mut d_inv_s = 0.0f64;
        let mut i = 0;
        for r in c.r0..c.r1 {
            let code = if app.n_codes > 0 {
                ctx.batch.codes.get(r).copied().unwrap_or(0) as usize
            } else {
                0
            };
            for _ in ctx.samples.range(r) {
                let da = sc.d_alpha[i];
                let ag = sc.alpha_grad[i];
                d_inv_s += (da * ag.d_inv_s).to_f64();
                let dci = &sc.d_color_in[i * dc..(i + 1) * dc];
                let dout = &mut sc.d_sdf_feature[i * fdim..(i + 1) * fdim];
                dout.copy_from_slice(&dci[..fdim]);
                dout[0] += da * ag.d_sdf;
                let dcos = da * ag.d_cos;
                let dir = sc.dirs[i];
                let mut dn = [T::ZERO; 3];
                for k in 0..3 {
                    dn[k] = dci[fdim + SH_DIM + k] + dcos * dir[k];
                }
                if app.n_codes > 0 {
                    let a0 = fdim + SH_DIM + 3;
                    let ga = &mut g.app[code * app.code_dim..(code + 1) * app.code_dim];
                    for (gv, &dv) in ga.iter_mut().zip(&dci[a0..a0 + app.code_dim]) {
                        *gv += dv;
                    }
                }
                let gr = sc.sdf_grad[i];
                let nr = sc.normal[i];
                let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
                let mut dg = [T::ZERO; 3];
                let tiny = T::from_f64(1e-12);
                if len > tiny {
                    let ndn = nr[0] * dn[0] + nr[1] * dn[1] + nr[2] * dn[2];
                    let e = c_eik * T::from_f64(2.0) * (len - T::ONE);
                    for k in 0..3 {
                        dg[k] = (dn[k] - nr[k] * ndn) / len + e * nr[k];
                    }
                } else {
                    for k in 0..3 {
                        dg[k] = dn[k] / tiny;
                    }
                }
                let (o, o1) = (sc.tap_off[i], sc.tap_off[i + 1]);
                if o1 - o == 3 {
                    // One-sided: ∇f_a = ±(f(x ± ε·e_a) − f(x)) / ε.
                    let sgn = c.one_sided_scale(sc.tap_sides[i]);
                    for k in 0..3 {
                        let v = dg[k] * sgn;
                        sc.d_tap_sdf[o + k] = v;
                        dout[0] -= v;
                    }
                } else {
                    for k in 0..3 {
                        let v = dg[k] * inv_2eps;
                        sc.d_tap_sdf[o + 2 * k] = v;
                        sc.d_tap_sdf[o + 2 * k + 1] = -v;
                    }
                }
                if w.curvature > 0.0 && o1 - o == 6 {
                    // Δf ≈ (Σ taps − 6 f(x)) / ε²; loss mean |Δf| (LossConfig::curvature).
                    let tp = &sc.tap_sdf[o..o1];
                    let lap = (tp.iter().fold(T::ZERO, |a, &v| a + v)
                        - T::from_f64(6.0) * sc.sdf_feature[i * fdim])
                        * inv_eps2;
                    sums.curv += k_curv * lap.to_f64().abs();
                    let sgn = if lap > T::ZERO {
                        c_curv
                    } else if lap < T::ZERO {
                        -c_curv
                    } else {
                        T::ZERO
                    };
                    for v in &mut sc.d_tap_sdf[o..o1] {
                        *v += sgn;
                    }
                    dout[0] -= T::from_f64(6.0) * sgn;
                }
                let e = len - T::ONE;
                sums.eik += (e * e).to_f64();
                i += 1;
            }
        }
        sums.d_inv_s += d_inv_s;
    }

    /// The SDF network's backward from `d_sdf_feature` (centres) and `d_tap_sdf` (taps):
    /// parameter gradients into `g.sdf`, `d_encoding` (hash-grid columns only, or every column
    /// with `all_cols`: the xyz prefix's gradient is needed only for the rays' gradient).
    #[inline]
    fn sdf_backward<T: Real>(
        &self,
        p: &Groups<T>,
        g: &mut GroupsMut<T>,
        c: &Chunk<T>,
        sc: &mut Scratch<T>,
        all_cols: bool,
    ) {
        let (n, fdim, d, wh) = (c.n, c.fdim, c.d, c.wh);
        let m = sc.tap_off[n];
        sc.d_sdf_hidden.resize((n + m) * wh, T::ZERO);
        {
            let h = sc.sdf_tape.acts.last().expect("hidden layer");
            let (dh_c, dh_t) = sc.d_sdf_hidden.split_at_mut(n * wh);
            self.sdf_mlp.backward_last(
                p.sdf,
                g.sdf,
                &h[..n * wh],
                n,
                fdim,
                &sc.d_sdf_feature,
                dh_c,
            );
            self.sdf_mlp
                .backward_last(p.sdf, g.sdf, &h[n * wh..], m, 1, &sc.d_tap_sdf, dh_t);
        }
        sc.d_encoding.resize((n + m + 1) * d, T::ZERO);
        // The spare row (the − taps of forward differences) carries no gradient.
        sc.d_encoding[(n + m) * d..].fill(T::ZERO);
        // Only the hash-grid columns of the input gradient unless the rays' gradient is wanted:
        // the xyz prefix has no parameters.
        let grid_cols = if all_cols { 0 } else { self.grid.xyz_dim() }..d;
        self.sdf_mlp.backward_hidden_cols(
            p.sdf,
            g.sdf,
            &sc.encoding,
            n + m,
            &sc.sdf_tape,
            &mut sc.d_sdf_hidden,
            &mut sc.mlp_work,
            Some((&mut sc.d_encoding, grid_cols)),
        );
    }

    /// The hash grid's backward: scatter-adds `d_encoding` into `g.hash`.
    #[inline]
    fn encode_backward<T: Real>(&self, g: &mut GroupsMut<T>, c: &Chunk<T>, sc: &Scratch<T>) {
        let (n, d, off, sides) = (c.n, c.d, &sc.tap_off, &sc.tap_sides);
        self.grid.encode_fd_backward_batch(
            &sc.points,
            &sc.tap_points,
            c.radius,
            c.active,
            &sc.d_encoding,
            |i| tap_rows(i, n, d, off, sides),
            g.hash,
        );
    }
}
