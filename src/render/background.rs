//! The learned background for training without masks: a small radiance field on the part of each
//! ray beyond the marched box, volume-rendered to a colour `C_bg` that replaces the constant
//! background behind the foreground.
//!
//! What the references do, and what is taken from each:
//! - NeuS (`models/renderer.py`, `render_core_outside`; `confs/womask.conf`, `n_outside = 32`):
//!   outside samples uniform in inverse distance (`z = far / s`, `s` stratified in
//!   `[1e-3, 1 − 1/(n+1)]`), each point `x` fed to a NeRF as NeRF++'s inverted-sphere coordinates
//!   `(x/|x|, 1/|x|)` with `|x|` clipped to `≥ 1`, density through `softplus`,
//!   `α = 1 − exp(−softplus(σ)·δ)`, colour through a sigmoid.
//! - instant-nsr-pl (`models/neus.py` `forward_bg_`, `configs/neus-dtu.yaml`
//!   `learned_background: true`): the background starts at the box's far intersection (or at
//!   the near plane for rays that miss the box) and the final colour is
//!   `C = C_fg + C_bg·(1 − O_fg)`. Its background field is a hash grid on the mip-NeRF 360
//!   contraction; here it is NeRF++'s inversion, as NeuS, with a frequency encoding (cheaper on a
//!   CPU than a second hash grid).
//!
//! This module's conventions (normalised space, `r` = `render.radius`, `n` = `n_outside`):
//! - Start `t₀`: the ray's exit from the box `[-r, r]³` that the foreground marches
//!   ([`super::rays::ray_aabb`]), or `0` (the origin) for a ray that misses the box or starts
//!   past it. Every point the foreground samples lies before `t₀` and every background point
//!   after it: no segment is rendered twice, so `C = C_fg + (1 − O_fg)·C_bg` is exactly front to
//!   back compositing of the two layers.
//! - Samples: stratum `k < n` covers `s ∈ [s_{k+1}, s_k]` with `s_k = 1 − (k/n)(1 − S_MIN)`, the
//!   sample at `s = 1 − (k + u)/n·(1 − S_MIN)` (`u` uniform in `[0,1)` when training, `½`
//!   otherwise), `t(s) = t₀ + r(1/s − 1)`, interval length `δ_k = t(s_{k+1}) − t(s_k)`. So the
//!   background spans `[t₀, t₀ + 999r]`, uniformly in inverse distance past `t₀` (NeuS's `far/s`,
//!   shifted to start exactly at `t₀` also for rays whose `t₀` is 0).
//! - Point `x = o + t·d`, `ρ = max(|x|, r)`, inverted-sphere point `q = (x/ρ, r/ρ)` (NeRF++ §4,
//!   scaled by `r`; `q₃ ∈ (0, 1]`, `1` at the box's inscribed sphere, `→ 0` at infinity).
//! - Encoding `γ(q) = [q, sin(2⁰q), cos(2⁰q), …, sin(2^{L−1}q), cos(2^{L−1}q)]` (NeuS's
//!   `Embedder` order, no `π`), width `4(1 + 2L)`; it carries no gradient (positions are fixed).
//! - Density network `γ(q) → (n_neurons, ReLU) × n_hidden_layers → 1 + F`: channel 0 is the raw
//!   density `σ`, channels `1..` a feature; colour network `[feature F, SH degree 4 of d (16)] →
//!   (n_neurons, ReLU) × color_hidden_layers → 3`, sigmoid (instant-nsr-pl `texture_bg`).
//! - `α_k = 1 − exp(−softplus(σ_k)·δ_k)` (units: `σ` per normalised unit), composited front to
//!   back over the background samples with the constant `render.background` (as the loss sees
//!   it) behind the last one: `C_bg = Σ w_k c_k + bg·(1 − O_bg)`. With zero density everywhere
//!   the model reduces exactly to the constant background.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::composite::{composite_backward, composite_forward, Composite};
use super::config::BackgroundConfig;
use super::rays::ray_aabb;
use crate::field::mlp::MlpTape;
use crate::field::sh::{sh4, SH_DIM};
use crate::field::{sigmoid, Activation, Mlp, Real};
use rand::Rng;

/// Smallest `s` of the inverse-distance strata (NeuS `linspace(1e-3, …)`): the last background
/// interval ends at `t₀ + r(1/S_MIN − 1) = t₀ + 999r`.
pub const S_MIN: f64 = 1e-3;

/// Distances of one ray's background samples (see the module docs): writes `t [n]` (sample
/// distances along the unit direction, normalised units) and `dt [n]` (interval lengths).
/// `jitter [n]`, each in `[0, 1)`, places the samples in their strata (`None`: the middle in
/// `s`). Always finite for a finite ray: a ray that misses the box, grazes it or starts inside
/// it gets the same `n` samples.
pub fn sample_background(
    o: [f32; 3],
    d: [f32; 3],
    radius: f32,
    n: usize,
    jitter: Option<&[f32]>,
    t: &mut [f32],
    dt: &mut [f32],
) {
    let t0 = ray_aabb(o, d, radius).map_or(0.0, |(_, t1)| t1) as f64;
    let r = radius as f64;
    let s_of = |u: f64| 1.0 - u * (1.0 - S_MIN);
    let t_of = |s: f64| t0 + r * (1.0 / s - 1.0);
    for k in 0..n {
        let u = jitter.map_or(0.5, |j| j[k] as f64);
        t[k] = t_of(s_of((k as f64 + u) / n as f64)) as f32;
        dt[k] = (t_of(s_of((k + 1) as f64 / n as f64)) - t_of(s_of(k as f64 / n as f64))) as f32;
    }
}

/// Background samples of a batch: `[n_rays][n_outside]` distances and interval lengths, ray
/// after ray.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BackgroundSamples {
    pub n_outside: usize,
    /// `[n_rays · n_outside]` sample distances (normalised units).
    pub t: Vec<f32>,
    /// `[n_rays · n_outside]` interval lengths.
    pub dt: Vec<f32>,
}

impl BackgroundSamples {
    /// Samples every ray of a batch; `rng` (if given) draws each sample's stratum offset.
    pub fn new<R: Rng>(
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        radius: f32,
        n_outside: usize,
        mut rng: Option<&mut R>,
    ) -> Self {
        let n = n_outside;
        let mut s = Self {
            n_outside,
            t: vec![0.0; origins.len() * n],
            dt: vec![0.0; origins.len() * n],
        };
        let mut jit = vec![0f32; n];
        for (i, (o, d)) in origins.iter().zip(dirs).enumerate() {
            let j = rng.as_mut().map(|rng| {
                jit.iter_mut().for_each(|v| *v = rng.random::<f32>());
                &jit[..]
            });
            let r = i * n..(i + 1) * n;
            sample_background(*o, *d, radius, n, j, &mut s.t[r.clone()], &mut s.dt[r]);
        }
        s
    }

    /// Sample index range of ray `ray`.
    pub fn range(&self, ray: usize) -> std::ops::Range<usize> {
        ray * self.n_outside..(ray + 1) * self.n_outside
    }
}

/// NeRF++'s inverted-sphere point `q = (x/ρ, r/ρ)`, `ρ = max(|x|, r)` (module docs).
pub fn invert_sphere(x: [f64; 3], radius: f64) -> [f64; 4] {
    let rho = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt().max(radius);
    [x[0] / rho, x[1] / rho, x[2] / rho, radius / rho]
}

/// Writes `γ(q)` (module docs) into `out [4(1 + 2L)]`.
pub fn frequency_encode<T: Real>(q: [f64; 4], n_freq: usize, out: &mut [T]) {
    for k in 0..4 {
        out[k] = T::from_f64(q[k]);
    }
    let mut f = 1.0;
    for l in 0..n_freq {
        let o = 4 + 8 * l;
        for k in 0..4 {
            let (s, c) = (f * q[k]).sin_cos();
            out[o + k] = T::from_f64(s);
            out[o + 4 + k] = T::from_f64(c);
        }
        f *= 2.0;
    }
}

/// `α = 1 − exp(−softplus(σ)·δ)` and `∂α/∂σ = exp(−softplus(σ)·δ)·δ·sigmoid(σ)` (NeuS
/// `render_core_outside`). Finite for every finite `σ` and `δ ≥ 0`: a saturated sample
/// (`softplus(σ)·δ` large) has `α = 1` and derivative 0, an empty one (`σ → −∞`) `α = 0`.
#[inline]
pub fn density_alpha<T: Real>(sigma: T, dt: T) -> (T, T) {
    let (sp, sg) = T::softplus_and_grad(sigma, T::ONE);
    let x = sp * dt;
    let alpha = -(-x).exp_m1();
    (alpha, (-x).exp() * dt * sg)
}

/// Colour of the background layer, `C_bg = Σ w_k c_k + behind·(1 − O_bg)`, from the samples'
/// `alpha [m]` and `rgb [m][3]`.
pub fn background_color<T: Real>(alpha: &[T], rgb: &[[T; 3]], behind: [T; 3]) -> [T; 3] {
    let mut c = [T::ZERO; 3];
    let mut trans = T::ONE;
    for i in 0..alpha.len() {
        let w = alpha[i] * trans;
        for k in 0..3 {
            c[k] += w * rgb[i][k];
        }
        trans *= T::ONE - alpha[i];
    }
    // 1 − O_bg is the final transmittance (Σ w_k = 1 − Π(1 − α_k)).
    for k in 0..3 {
        c[k] += behind[k] * trans;
    }
    c
}

/// One ray's samples of one layer (see [`composite_forward`]): `alpha [m]`, `rgb [m][3]`,
/// distances `t [m]` (normalised units).
#[derive(Clone, Copy)]
pub struct Layer<'a, T> {
    pub alpha: &'a [T],
    pub rgb: &'a [[T; 3]],
    pub t: &'a [T],
}

/// Forward of the two layers of one ray: the background's colour `C_bg` (on `behind`), then the
/// foreground composited on it, `C = Σ w_i c_i + (1 − O_fg)·C_bg` (instant-nsr-pl
/// `models/neus.py`). The returned opacity, depth and normal are the foreground's. Also returns
/// `C_bg`, which [`composite_two_backward`] needs.
pub fn composite_two_forward<T: Real>(
    fg: Layer<'_, T>,
    fg_normal: &[[T; 3]],
    bg: Layer<'_, T>,
    behind: [T; 3],
) -> (Composite<T>, [T; 3]) {
    let c_bg = background_color(bg.alpha, bg.rgb, behind);
    (
        composite_forward(fg.alpha, fg.rgb, fg.t, fg_normal, c_bg),
        c_bg,
    )
}

/// Gradients of one ray's loss, `∂L/∂C`, `∂L/∂O_fg`, `∂L/∂D_fg`.
#[derive(Clone, Copy, Debug)]
pub struct RayGrad<T> {
    pub rgb: [T; 3],
    pub opacity: T,
    pub depth: T,
}

/// Backward of [`composite_two_forward`]: writes `d_fg_alpha [m]`, `d_fg_rgb [m][3]`,
/// `d_bg_alpha [k]`, `d_bg_rgb [k][3]`. `c_bg` and `fg_opacity` are the forward's. Since
/// `∂C/∂C_bg = (1 − O_fg)`, the background's gradient is the foreground's backward with
/// `C_bg` as its constant background, followed by the background layer's own with
/// `g = ∂L/∂C·(1 − O_fg)`.
#[allow(clippy::too_many_arguments)]
pub fn composite_two_backward<T: Real>(
    fg: Layer<'_, T>,
    bg: Layer<'_, T>,
    behind: [T; 3],
    c_bg: [T; 3],
    fg_opacity: T,
    g: RayGrad<T>,
    d_fg_alpha: &mut [T],
    d_fg_rgb: &mut [[T; 3]],
    d_bg_alpha: &mut [T],
    d_bg_rgb: &mut [[T; 3]],
) {
    composite_backward(
        fg.alpha, fg.rgb, fg.t, c_bg, g.rgb, g.opacity, g.depth, d_fg_alpha, d_fg_rgb,
    );
    let g_bg = g.rgb.map(|v| v * (T::ONE - fg_opacity));
    composite_backward(
        bg.alpha,
        bg.rgb,
        bg.t,
        behind,
        g_bg,
        T::ZERO,
        T::ZERO,
        d_bg_alpha,
        d_bg_rgb,
    );
}

/// The background's two networks (shapes only; parameters live in the flat buffer, groups
/// `bg_density` and `bg_color`).
#[derive(Debug, Clone)]
pub struct BackgroundField {
    /// `γ(q) [4(1 + 2L)] → … → 1 + F` (ReLU hidden layers, linear output).
    pub density: Mlp,
    /// `[F + 16] → … → 3` (ReLU hidden layers, logits; the sigmoid is applied here).
    pub color: Mlp,
    pub n_outside: usize,
    pub n_frequencies: usize,
    pub feature_dim: usize,
}

/// Per-shard buffers of the background field, reused across chunks. Shapes: `nb` background
/// samples of the chunk (its rays × `n_outside`, ray after ray), `de = 4(1 + 2L)`,
/// `fo = 1 + F`, `dc = F + 16`; rows row-major.
#[derive(Default)]
pub struct BackgroundScratch<T> {
    /// `[nb][de]` encodings `γ(q)`.
    pub enc: Vec<T>,
    pub density_tape: MlpTape<T>,
    /// `[nb][fo]` density network outputs (raw density, feature).
    pub density_out: Vec<T>,
    /// `[nb][dc]` colour network inputs (feature, SH of the direction).
    pub color_in: Vec<T>,
    pub color_tape: MlpTape<T>,
    /// `[nb][3]` colour logits.
    pub logits: Vec<T>,
    /// `[nb][3]` sample colours.
    pub rgb: Vec<[T; 3]>,
    /// `[nb]` alphas and `[nb]` `∂α/∂σ`.
    pub alpha: Vec<T>,
    pub d_alpha_d_sigma: Vec<T>,
    /// `[nb]` `∂L/∂α`, `[nb][3]` `∂L/∂rgb` (filled by the compositing backward).
    pub d_alpha: Vec<T>,
    pub d_rgb: Vec<[T; 3]>,
    /// Backward work buffers: `[nb][3]`, `[nb][last hidden]`, `[nb][dc]`, `[nb][fo]`.
    pub d_logits: Vec<T>,
    pub d_color_hidden: Vec<T>,
    pub d_color_in: Vec<T>,
    pub d_density_out: Vec<T>,
    pub d_density_hidden: Vec<T>,
    pub mlp_work: Vec<T>,
}

impl BackgroundField {
    /// The networks of `cfg` (which must be enabled and validated by [`Self::validate`]).
    pub fn new(cfg: &BackgroundConfig) -> Self {
        let de = 4 * (1 + 2 * cfg.n_frequencies);
        let mut dd = vec![de];
        dd.extend(std::iter::repeat_n(cfg.n_neurons, cfg.n_hidden_layers));
        dd.push(1 + cfg.feature_dim);
        let mut dc = vec![cfg.feature_dim + SH_DIM];
        dc.extend(std::iter::repeat_n(cfg.n_neurons, cfg.color_hidden_layers));
        dc.push(3);
        Self {
            density: Mlp::new(dd, Activation::Relu),
            color: Mlp::new(dc, Activation::Relu),
            n_outside: cfg.n_outside,
            n_frequencies: cfg.n_frequencies,
            feature_dim: cfg.feature_dim,
        }
    }

    /// `None` when `cfg` is usable, else the offending key and why.
    pub fn validate(cfg: &BackgroundConfig) -> Option<(&'static str, usize, &'static str)> {
        let checks = [
            ("model.background.n_outside", cfg.n_outside, 1, 4096),
            ("model.background.n_frequencies", cfg.n_frequencies, 0, 16),
            ("model.background.n_neurons", cfg.n_neurons, 1, 1024),
            (
                "model.background.n_hidden_layers",
                cfg.n_hidden_layers,
                1,
                16,
            ),
            (
                "model.background.color_hidden_layers",
                cfg.color_hidden_layers,
                1,
                16,
            ),
            ("model.background.feature_dim", cfg.feature_dim, 0, 1024),
        ];
        checks
            .into_iter()
            .find(|&(_, v, lo, hi)| v < lo || v > hi)
            .map(|(k, v, lo, _)| {
                (
                    k,
                    v,
                    if lo == 0 {
                        "is out of range (at most 16 frequencies, 1024 features)"
                    } else {
                        "must be at least 1 (and at most 4096 samples, 16 layers, 1024 neurons)"
                    },
                )
            })
    }

    /// Encoding width `4(1 + 2L)`.
    pub fn encoding_dim(&self) -> usize {
        self.density.input_dim()
    }

    /// Forward on `nb` background samples: positions `x [nb][3]` (normalised space), unit
    /// directions `dirs [nb][3]` and interval lengths `dt [nb]` (normalised units). Fills
    /// `sc.rgb`, `sc.alpha` and (for the backward) the tapes and `sc.d_alpha_d_sigma`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward<T: Real>(
        &self,
        p_density: &[T],
        p_color: &[T],
        x: &[[f64; 3]],
        dirs: &[[T; 3]],
        dt: &[T],
        radius: f64,
        sc: &mut BackgroundScratch<T>,
    ) {
        let nb = x.len();
        let (de, fo, f) = (self.encoding_dim(), 1 + self.feature_dim, self.feature_dim);
        let dc = f + SH_DIM;
        sc.enc.resize(nb * de, T::ZERO);
        for i in 0..nb {
            let q = invert_sphere(x[i], radius);
            frequency_encode(q, self.n_frequencies, &mut sc.enc[i * de..(i + 1) * de]);
        }
        self.density
            .forward_hidden(p_density, &sc.enc, nb, &mut sc.density_tape);
        sc.density_out.resize(nb * fo, T::ZERO);
        {
            let h = sc.density_tape.acts.last().expect("hidden layer");
            self.density
                .forward_last(p_density, h, nb, fo, &mut sc.density_out);
        }
        sc.color_in.resize(nb * dc, T::ZERO);
        for i in 0..nb {
            let row = &mut sc.color_in[i * dc..(i + 1) * dc];
            row[..f].copy_from_slice(&sc.density_out[i * fo + 1..(i + 1) * fo]);
            sh4(dirs[i], &mut row[f..]);
        }
        self.color
            .forward_hidden(p_color, &sc.color_in, nb, &mut sc.color_tape);
        sc.logits.resize(nb * 3, T::ZERO);
        {
            let h = sc.color_tape.acts.last().expect("hidden layer");
            self.color.forward_last(p_color, h, nb, 3, &mut sc.logits);
        }
        sc.rgb.resize(nb, [T::ZERO; 3]);
        sc.alpha.resize(nb, T::ZERO);
        sc.d_alpha_d_sigma.resize(nb, T::ZERO);
        for i in 0..nb {
            for k in 0..3 {
                sc.rgb[i][k] = sigmoid(sc.logits[3 * i + k]);
            }
            let (a, da) = density_alpha(sc.density_out[i * fo], dt[i]);
            sc.alpha[i] = a;
            sc.d_alpha_d_sigma[i] = da;
        }
    }

    /// Backward from `sc.d_alpha` and `sc.d_rgb` (after [`Self::forward`] on the same `nb`
    /// samples): adds the parameter gradients into `g_density` and `g_color`.
    pub fn backward<T: Real>(
        &self,
        p_density: &[T],
        p_color: &[T],
        g_density: &mut [T],
        g_color: &mut [T],
        sc: &mut BackgroundScratch<T>,
    ) {
        let nb = sc.alpha.len();
        let (fo, f) = (1 + self.feature_dim, self.feature_dim);
        let dc = f + SH_DIM;
        sc.d_logits.resize(nb * 3, T::ZERO);
        for i in 0..nb {
            for k in 0..3 {
                let y = sc.rgb[i][k];
                sc.d_logits[3 * i + k] = sc.d_rgb[i][k] * y * (T::ONE - y);
            }
        }
        sc.d_color_hidden
            .resize(nb * self.color.last_hidden_dim(), T::ZERO);
        sc.d_color_in.resize(nb * dc, T::ZERO);
        {
            let h = sc.color_tape.acts.last().expect("hidden layer");
            self.color.backward_last(
                p_color,
                g_color,
                h,
                nb,
                3,
                &sc.d_logits,
                &mut sc.d_color_hidden,
            );
        }
        self.color.backward_hidden(
            p_color,
            g_color,
            &sc.color_in,
            nb,
            &sc.color_tape,
            &mut sc.d_color_hidden,
            &mut sc.mlp_work,
            Some(&mut sc.d_color_in),
        );
        sc.d_density_out.resize(nb * fo, T::ZERO);
        for i in 0..nb {
            let row = &mut sc.d_density_out[i * fo..(i + 1) * fo];
            row[0] = sc.d_alpha[i] * sc.d_alpha_d_sigma[i];
            row[1..].copy_from_slice(&sc.d_color_in[i * dc..i * dc + f]);
        }
        sc.d_density_hidden
            .resize(nb * self.density.last_hidden_dim(), T::ZERO);
        {
            let h = sc.density_tape.acts.last().expect("hidden layer");
            self.density.backward_last(
                p_density,
                g_density,
                h,
                nb,
                fo,
                &sc.d_density_out,
                &mut sc.d_density_hidden,
            );
        }
        self.density.backward_hidden(
            p_density,
            g_density,
            &sc.enc,
            nb,
            &sc.density_tape,
            &mut sc.d_density_hidden,
            &mut sc.mlp_work,
            None,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[allow(clippy::too_many_arguments)]
    fn ray_loss(
        fa: &[f64],
        fc: &[[f64; 3]],
        ba: &[f64],
        bc: &[[f64; 3]],
        ft: &[f64],
        bt: &[f64],
        behind: [f64; 3],
        g: [f64; 5],
    ) -> f64 {
        let n = vec![[0.0, 0.0, 1.0]; fa.len()];
        let fg = Layer {
            alpha: fa,
            rgb: fc,
            t: ft,
        };
        let bg = Layer {
            alpha: ba,
            rgb: bc,
            t: bt,
        };
        let (o, _) = composite_two_forward(fg, &n, bg, behind);
        g[0] * o.rgb[0] + g[1] * o.rgb[1] + g[2] * o.rgb[2] + g[3] * o.opacity + g[4] * o.depth
    }

    /// The two-layer compositing backward against central differences in f64, with the hard
    /// cases: empty foreground (a ray that misses the box), saturated and empty layers.
    #[test]
    fn two_layer_backward_matches_central_differences() {
        let behind = [1.0, 0.9, 0.8];
        let g = [0.3, -1.2, 0.7, 0.9, -0.4];
        let cases: [(Vec<f64>, Vec<f64>); 6] = [
            (vec![0.1, 0.5, 0.3], vec![0.2, 0.6, 0.9]),
            (vec![], vec![0.3, 0.4]),
            (vec![1.0, 1.0], vec![0.5, 0.5]),
            (vec![0.2, 0.1], vec![0.0, 0.0, 0.0]),
            (vec![0.0, 0.0], vec![1.0, 1.0]),
            (vec![0.999, 0.3], vec![0.999, 1.0]),
        ];
        let mut fails = Vec::new();
        for (fa, ba) in cases {
            let (m, k) = (fa.len(), ba.len());
            let fc: Vec<[f64; 3]> = (0..m)
                .map(|i| [0.1 * i as f64, 0.5, 0.9 - 0.2 * i as f64])
                .collect();
            let bc: Vec<[f64; 3]> = (0..k)
                .map(|i| [0.7 - 0.1 * i as f64, 0.2, 0.3 + 0.1 * i as f64])
                .collect();
            let ft: Vec<f64> = (0..m).map(|i| 1.0 + 0.1 * i as f64).collect();
            let bt: Vec<f64> = (0..k).map(|i| 3.0 + i as f64).collect();
            let n = vec![[0.0, 0.0, 1.0]; m];
            let fg = Layer {
                alpha: &fa[..],
                rgb: &fc[..],
                t: &ft[..],
            };
            let bg = Layer {
                alpha: &ba[..],
                rgb: &bc[..],
                t: &bt[..],
            };
            let (o, c_bg) = composite_two_forward(fg, &n, bg, behind);
            let (mut dfa, mut dfc) = (vec![0.0; m], vec![[0.0; 3]; m]);
            let (mut dba, mut dbc) = (vec![0.0; k], vec![[0.0; 3]; k]);
            composite_two_backward(
                fg,
                bg,
                behind,
                c_bg,
                o.opacity,
                RayGrad {
                    rgb: [g[0], g[1], g[2]],
                    opacity: g[3],
                    depth: g[4],
                },
                &mut dfa,
                &mut dfc,
                &mut dba,
                &mut dbc,
            );
            let all = dfa
                .iter()
                .chain(&dba)
                .chain(dfc.iter().chain(&dbc).flatten());
            assert!(all.into_iter().all(|v| v.is_finite()));
            let h = 1e-6;
            let l = |fa: &[f64], fc: &[[f64; 3]], ba: &[f64], bc: &[[f64; 3]]| {
                ray_loss(fa, fc, ba, bc, &ft, &bt, behind, g)
            };
            let mut check = |what: String, an: f64, fd: f64| {
                if (fd - an).abs() > 1e-7 + 1e-6 * fd.abs() {
                    fails.push(format!("{what}: analytic {an} fd {fd}"));
                }
            };
            for i in 0..m {
                let (mut p, mut q) = (fa.clone(), fa.clone());
                p[i] += h;
                q[i] -= h;
                let fd = (l(&p, &fc, &ba, &bc) - l(&q, &fc, &ba, &bc)) / (2.0 * h);
                check(format!("{fa:?}/{ba:?} d_fg_alpha[{i}]"), dfa[i], fd);
                for c in 0..3 {
                    let (mut p, mut q) = (fc.clone(), fc.clone());
                    p[i][c] += h;
                    q[i][c] -= h;
                    let fd = (l(&fa, &p, &ba, &bc) - l(&fa, &q, &ba, &bc)) / (2.0 * h);
                    check(format!("{fa:?}/{ba:?} d_fg_rgb[{i}][{c}]"), dfc[i][c], fd);
                }
            }
            for i in 0..k {
                let (mut p, mut q) = (ba.clone(), ba.clone());
                p[i] += h;
                q[i] -= h;
                let fd = (l(&fa, &fc, &p, &bc) - l(&fa, &fc, &q, &bc)) / (2.0 * h);
                check(format!("{fa:?}/{ba:?} d_bg_alpha[{i}]"), dba[i], fd);
                for c in 0..3 {
                    let (mut p, mut q) = (bc.clone(), bc.clone());
                    p[i][c] += h;
                    q[i][c] -= h;
                    let fd = (l(&fa, &fc, &ba, &p) - l(&fa, &fc, &ba, &q)) / (2.0 * h);
                    check(format!("{fa:?}/{ba:?} d_bg_rgb[{i}][{c}]"), dbc[i][c], fd);
                }
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }

    /// Limits: a transparent background is the constant colour; an opaque foreground hides the
    /// background; no sample at all gives `behind`.
    #[test]
    fn two_layer_limits() {
        let behind = [0.3, 0.2, 0.1];
        let c = background_color(&[0.0, 0.0], &[[0.9; 3], [0.9; 3]], behind);
        assert_eq!(c, behind);
        let c = background_color::<f64>(&[], &[], behind);
        assert_eq!(c, behind);
        let fa = [1.0];
        let fc = [[0.25, 0.5, 0.75]];
        let ft = [1.0];
        let n = [[0.0, 0.0, 1.0]];
        let ba = [1.0];
        let bc = [[0.9, 0.9, 0.9]];
        let bt = [5.0];
        let fg = Layer {
            alpha: &fa[..],
            rgb: &fc[..],
            t: &ft[..],
        };
        let bg = Layer {
            alpha: &ba[..],
            rgb: &bc[..],
            t: &bt[..],
        };
        let (o, c_bg) = composite_two_forward(fg, &n, bg, behind);
        assert_eq!(o.rgb, fc[0]);
        assert_eq!(c_bg, bc[0]);
        let empty = Layer {
            alpha: &[][..],
            rgb: &[][..],
            t: &[][..],
        };
        let (o, _) = composite_two_forward(empty, &[], bg, behind);
        assert_eq!(o.rgb, bc[0]);
        assert_eq!(o.opacity, 0.0);
    }

    /// `density_alpha` against central differences, and finite at the extremes (zero density,
    /// saturated density, zero and huge intervals).
    #[test]
    fn density_alpha_gradient_and_extremes() {
        for sigma in [-3.0, -0.2, 0.0, 0.7, 4.0] {
            for dt in [0.01, 0.5, 3.0] {
                let (_, an) = density_alpha(sigma, dt);
                let h = 1e-6;
                let fd =
                    (density_alpha(sigma + h, dt).0 - density_alpha(sigma - h, dt).0) / (2.0 * h);
                assert!(
                    (an - fd).abs() < 1e-8 + 1e-6 * fd.abs(),
                    "σ {sigma} δ {dt}: {an} vs {fd}"
                );
            }
        }
        for (sigma, dt) in [
            (-1e4f32, 1.0f32),
            (1e4, 1.0),
            (1e30, 1e3),
            (0.0, 0.0),
            (5.0, 1e30),
        ] {
            let (a, d) = density_alpha(sigma, dt);
            assert!(a.is_finite() && d.is_finite(), "σ {sigma} δ {dt}: {a} {d}");
            assert!((0.0..=1.0).contains(&a), "σ {sigma} δ {dt}: α {a}");
        }
        assert_eq!(density_alpha(-1e4f32, 1.0).0, 0.0, "zero density");
        assert_eq!(density_alpha(1e4f32, 1.0), (1.0, 0.0), "saturated");
    }

    /// Samples of the hard rays: through the box, starting inside it, grazing its edge, missing
    /// it and pointing away from it: `n` finite samples past `t₀`, increasing, in their strata,
    /// with positive intervals that tile `[t₀, t₀ + 999r]`, and valid inverted-sphere points.
    #[test]
    fn background_samples_of_hard_rays() {
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let r = 1.0f32;
        let rays: [([f32; 3], [f32; 3], f32); 5] = [
            ([0.0, 0.0, -3.0], [0.0, 0.0, 1.0], 4.0),
            ([0.2, 0.1, 0.3], [0.0, 1.0, 0.0], 0.9),
            ([-2.0, 0.0, 0.0], [s, s, 0.0], 0.0),
            ([0.0, 3.0, -3.0], [0.0, 0.0, 1.0], 0.0),
            ([0.0, 0.0, 3.0], [0.0, 0.0, 1.0], 0.0),
        ];
        let n = 8;
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        for (o, d, t0) in rays {
            for jitter in [
                None,
                Some((0..n).map(|_| rng.random::<f32>()).collect::<Vec<_>>()),
            ] {
                let (mut t, mut dt) = (vec![0f32; n], vec![0f32; n]);
                sample_background(o, d, r, n, jitter.as_deref(), &mut t, &mut dt);
                let mut edge = t0 as f64;
                for k in 0..n {
                    assert!(t[k].is_finite() && dt[k] > 0.0, "{o:?} {k}: {t:?} {dt:?}");
                    assert!(
                        t[k] as f64 >= edge - 1e-4 && (t[k] as f64) <= edge + dt[k] as f64 + 1e-3,
                        "{o:?}: sample {k} at {} outside its stratum [{edge}, +{}]",
                        t[k],
                        dt[k]
                    );
                    edge += dt[k] as f64;
                    let x = [0, 1, 2].map(|a| (o[a] + d[a] * t[k]) as f64);
                    let q = invert_sphere(x, r as f64);
                    assert!(q.iter().all(|v| v.is_finite()) && q[3] > 0.0 && q[3] <= 1.0);
                    let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                    assert!((len - 1.0).abs() < 1e-9 || q[3] == 1.0, "{q:?}");
                }
                let want = t0 as f64 + 999.0 * r as f64;
                assert!((edge - want).abs() < 1e-2 * want, "{o:?}: {edge} vs {want}");
            }
        }
        // Uniform in inverse distance: equal steps of 1/(t − t₀ + r) between the midpoints.
        let (mut t, mut dt) = (vec![0f32; 4], vec![0f32; 4]);
        sample_background(
            [0.0, 0.0, -3.0],
            [0.0, 0.0, 1.0],
            1.0,
            4,
            None,
            &mut t,
            &mut dt,
        );
        let inv: Vec<f64> = t.iter().map(|&v| 1.0 / (v as f64 - 4.0 + 1.0)).collect();
        let step = inv[0] - inv[1];
        for w in inv.windows(2) {
            assert!(((w[0] - w[1]) - step).abs() < 1e-5, "{inv:?}");
        }
    }

    /// The field's forward and backward against central differences in f64 (a loss that weighs
    /// every sample's alpha and colour), on samples near and far.
    #[test]
    fn field_backward_matches_central_differences() {
        let cfg = BackgroundConfig {
            kind: super::super::config::BackgroundKind::Nerfpp,
            n_outside: 4,
            n_frequencies: 2,
            n_neurons: 16,
            n_hidden_layers: 2,
            color_hidden_layers: 1,
            feature_dim: 3,
        };
        assert!(BackgroundField::validate(&cfg).is_none());
        let field = BackgroundField::new(&cfg);
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let mut pd = vec![0f32; field.density.n_params()];
        let mut pc = vec![0f32; field.color.n_params()];
        field.density.init_kaiming(&mut pd, &mut rng);
        field.color.init_kaiming(&mut pc, &mut rng);
        let mut pd: Vec<f64> = pd
            .iter()
            .map(|&v| v as f64 + rng.random_range(-0.1..0.1))
            .collect();
        let mut pc: Vec<f64> = pc
            .iter()
            .map(|&v| v as f64 + rng.random_range(-0.1..0.1))
            .collect();
        let nb = 6;
        let x: Vec<[f64; 3]> = (0..nb)
            .map(|i| [1.5 + i as f64 * 3.0, -0.5 * i as f64, 2.0])
            .collect();
        let dirs: Vec<[f64; 3]> = (0..nb).map(|_| [0.6, 0.0, 0.8]).collect();
        let dt: Vec<f64> = (0..nb).map(|i| 0.3 * (i + 1) as f64).collect();
        let wa: Vec<f64> = (0..nb).map(|_| rng.random_range(-1.0..1.0)).collect();
        let wc: Vec<[f64; 3]> = (0..nb)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let loss = |pd: &[f64], pc: &[f64]| {
            let mut sc = BackgroundScratch::default();
            field.forward(pd, pc, &x, &dirs, &dt, 1.0, &mut sc);
            (0..nb)
                .map(|i| wa[i] * sc.alpha[i] + (0..3).map(|k| wc[i][k] * sc.rgb[i][k]).sum::<f64>())
                .sum::<f64>()
        };
        let mut sc = BackgroundScratch::default();
        field.forward(&pd, &pc, &x, &dirs, &dt, 1.0, &mut sc);
        sc.d_alpha = wa.clone();
        sc.d_rgb = wc.clone();
        let (mut gd, mut gc) = (vec![0.0; pd.len()], vec![0.0; pc.len()]);
        field.backward(&pd, &pc, &mut gd, &mut gc, &mut sc);
        let h = 1e-6;
        let mut fails = Vec::new();
        let mut nonzero = 0;
        for i in 0..pd.len() {
            let old = pd[i];
            pd[i] = old + h;
            let lp = loss(&pd, &pc);
            pd[i] = old - h;
            let lm = loss(&pd, &pc);
            pd[i] = old;
            let fd = (lp - lm) / (2.0 * h);
            nonzero += (gd[i] != 0.0) as usize;
            if (fd - gd[i]).abs() > 1e-7 + 1e-5 * fd.abs().max(gd[i].abs()) {
                fails.push(format!("density[{i}]: {} vs fd {fd}", gd[i]));
            }
        }
        for i in 0..pc.len() {
            let old = pc[i];
            pc[i] = old + h;
            let lp = loss(&pd, &pc);
            pc[i] = old - h;
            let lm = loss(&pd, &pc);
            pc[i] = old;
            let fd = (lp - lm) / (2.0 * h);
            nonzero += (gc[i] != 0.0) as usize;
            if (fd - gc[i]).abs() > 1e-7 + 1e-5 * fd.abs().max(gc[i].abs()) {
                fails.push(format!("color[{i}]: {} vs fd {fd}", gc[i]));
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
        assert!(nonzero > (pd.len() + pc.len()) / 2, "{nonzero} nonzero");
    }
}
