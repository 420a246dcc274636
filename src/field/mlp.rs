//! Batched fully connected networks with hand-written backward passes.
//!
//! Parameter layout inside the network's slice of the flat buffer: for each layer `l`, the weight
//! `W_l` as `[out][in]` row-major (PyTorch `nn.Linear` layout), then the bias `b_l [out]`.
//! Activations are row-major `[n][width]`. Hidden layers use [`Activation`]; the last layer is
//! linear (output activations such as the colour sigmoid are applied by the caller).
//!
//! Matrix products of widths 16/32/64 go through the register-blocked kernels of
//! [`super::dense`] where the build has them ([`dense::KERNEL`]: AVX-512 or AVX2+FMA; activation
//! and derivative fused into the product's epilogue, outputs narrower than 16 zero-padded to 16);
//! other widths, and every width on other builds, through [`Real::gemm`] (`matrixmultiply`).
//! The dispatch rule and the measured figures are in [`super::dense`]'s docs.
//! [`linear_forward_naive`] is the slow reference the tests compare against, and the
//! finite-difference tests cover both the specialised and the other widths.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::dense::{self, Init, Strided};
use super::Real;
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// Hidden-layer activation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Activation {
    /// `max(z, 0)`; derivative taken as 0 at 0 (PyTorch).
    Relu,
    /// `ln(1 + e^{βz})/β`, linear above `βz > 20` (PyTorch `nn.Softplus` threshold).
    Softplus { beta: f32 },
}

impl Activation {
    #[inline(always)]
    pub fn apply<T: Real>(self, z: T) -> T {
        match self {
            Activation::Relu => z.maxv(T::ZERO),
            Activation::Softplus { beta } => {
                let b = T::from_f32(beta);
                let bz = b * z;
                if bz > T::from_f64(20.0) {
                    z
                } else {
                    bz.exp().ln_1p() / b
                }
            }
        }
    }

    /// Derivative `dy/dz` written in terms of the output `y` (so only outputs are stored):
    /// Softplus: `σ(βz) = 1 − e^{−βy}`.
    #[inline(always)]
    pub fn derivative_from_output<T: Real>(self, y: T) -> T {
        match self {
            Activation::Relu => {
                if y > T::ZERO {
                    T::ONE
                } else {
                    T::ZERO
                }
            }
            Activation::Softplus { beta } => -(-(T::from_f32(beta) * y)).exp_m1(),
        }
    }
}

/// Widths the build's register kernel ([`dense::KERNEL`]) specialises.
fn fast_width(w: usize) -> bool {
    dense::KERNEL.specialises(w)
}

/// `Wᵀ` (`[d_in][d_out]`, the k-major operand of the register kernel) of `W [d_out][d_in]`.
fn transpose<T: Real>(w: &[T], d_in: usize, d_out: usize) -> Vec<T> {
    let mut wt = vec![T::ZERO; d_in * d_out];
    for o in 0..d_out {
        for i in 0..d_in {
            wt[i * d_out + o] = w[o * d_in + i];
        }
    }
    wt
}

/// `y[n][d_out] = x[n][d_in] · W[d_out][d_in]ᵀ + b`, then `post(row, y_row)` on each output row
/// (fused activations). Register kernel ([`dense`]) for output widths 16/32/64, `matrixmultiply`
/// otherwise.
#[allow(clippy::too_many_arguments)]
pub fn linear_forward_then<T: Real, F: FnMut(usize, &mut [T])>(
    w: &[T],
    b: &[T],
    x: &[T],
    n: usize,
    d_in: usize,
    d_out: usize,
    y: &mut [T],
    post: F,
) {
    assert!(w.len() >= d_out * d_in && b.len() >= d_out);
    assert!(x.len() >= n * d_in && y.len() >= n * d_out);
    let a = Strided::row_major(x, d_in);
    if fast_width(d_out) {
        let wt = transpose(&w[..d_out * d_in], d_in, d_out);
        dense::gemm_then(n, d_in, d_out, a, &wt, d_out, y, d_out, Init::Bias(b), post);
    } else if d_out < 16 && fast_width(16) {
        // Narrow outputs (the SDF network's 13 channels, the colour network's 3): zero-padded to
        // 16 columns for the register kernel, then copied out.
        const P: usize = 16;
        let mut wt = vec![T::ZERO; d_in * P];
        let mut bp = [T::ZERO; P];
        bp[..d_out].copy_from_slice(&b[..d_out]);
        for o in 0..d_out {
            for i in 0..d_in {
                wt[i * P + o] = w[o * d_in + i];
            }
        }
        let mut t = vec![T::ZERO; n * P];
        let mut post = post;
        dense::gemm_then(
            n,
            d_in,
            P,
            a,
            &wt,
            P,
            &mut t,
            P,
            Init::Bias(&bp),
            |i, row| post(i, &mut row[..d_out]),
        );
        for (yr, tr) in y[..n * d_out]
            .chunks_exact_mut(d_out)
            .zip(t.chunks_exact(P))
        {
            yr.copy_from_slice(&tr[..d_out]);
        }
    } else {
        // W row-major is Wᵀ with strides (1, d_in): matrixmultiply takes any strides.
        for row in y[..n * d_out].chunks_exact_mut(d_out) {
            row.copy_from_slice(&b[..d_out]);
        }
        if n > 0 && d_in > 0 {
            // SAFETY: sizes checked above; A = x (n×d_in), B = Wᵀ (d_in×d_out), C = y (n×d_out).
            unsafe {
                T::gemm(
                    n,
                    d_in,
                    d_out,
                    T::ONE,
                    x.as_ptr(),
                    d_in as isize,
                    1,
                    w.as_ptr(),
                    1,
                    d_in as isize,
                    T::ONE,
                    y.as_mut_ptr(),
                    d_out as isize,
                    1,
                );
            }
        }
        let mut post = post;
        for (i, row) in y[..n * d_out].chunks_exact_mut(d_out).enumerate() {
            post(i, row);
        }
    }
}

/// `y[n][d_out] = x[n][d_in] · W[d_out][d_in]ᵀ + b` (see [`linear_forward_then`]).
pub fn linear_forward<T: Real>(
    w: &[T],
    b: &[T],
    x: &[T],
    n: usize,
    d_in: usize,
    d_out: usize,
    y: &mut [T],
) {
    linear_forward_then(w, b, x, n, d_in, d_out, y, |_, _| {});
}

/// Slow reference of [`linear_forward`]: three nested loops.
pub fn linear_forward_naive<T: Real>(
    w: &[T],
    b: &[T],
    x: &[T],
    n: usize,
    d_in: usize,
    d_out: usize,
    y: &mut [T],
) {
    for i in 0..n {
        for o in 0..d_out {
            let mut s = b[o];
            for k in 0..d_in {
                s += x[i * d_in + k] * w[o * d_in + k];
            }
            y[i * d_out + o] = s;
        }
    }
}

/// Backward of [`linear_forward`]: `gw += dyᵀ·x`, `gb += Σ_rows dy`, and, if given,
/// `dx = dy·W` (overwritten).
#[allow(clippy::too_many_arguments)]
pub fn linear_backward<T: Real>(
    w: &[T],
    x: &[T],
    dy: &[T],
    n: usize,
    d_in: usize,
    d_out: usize,
    gw: &mut [T],
    gb: &mut [T],
    dx: Option<&mut [T]>,
) {
    linear_backward_cols(w, x, dy, n, d_in, d_out, gw, gb, dx.map(|d| (d, 0..d_in)));
}

/// [`linear_backward`] computing only the input-gradient columns `cols` of
/// `dx [n][d_in]` (the others are left as they are): the SDF network's hash-grid columns, whose
/// width the register kernels specialise, skipping the xyz columns nothing consumes.
#[allow(clippy::too_many_arguments)]
pub fn linear_backward_cols<T: Real>(
    w: &[T],
    x: &[T],
    dy: &[T],
    n: usize,
    d_in: usize,
    d_out: usize,
    gw: &mut [T],
    gb: &mut [T],
    dx: Option<(&mut [T], std::ops::Range<usize>)>,
) {
    assert!(w.len() >= d_out * d_in && gw.len() >= d_out * d_in && gb.len() >= d_out);
    assert!(x.len() >= n * d_in && dy.len() >= n * d_out);
    if n == 0 {
        return;
    }
    // gw (d_out×d_in) += dyᵀ (d_out×n) · x (n×d_in).
    let dyt = Strided::transposed(dy, d_out);
    if fast_width(d_in) || !fast_width(d_out) {
        dense::gemm(d_out, n, d_in, dyt, x, d_in, gw, d_in, Init::Accumulate);
    } else {
        // gwᵀ (d_in×d_out) = xᵀ · dy with the register kernel, then added transposed.
        let xt = Strided::transposed(x, d_in);
        let mut t = vec![T::ZERO; d_in * d_out];
        dense::gemm(d_in, n, d_out, xt, dy, d_out, &mut t, d_out, Init::Zero);
        for o in 0..d_out {
            for i in 0..d_in {
                gw[o * d_in + i] += t[i * d_out + o];
            }
        }
    }
    for row in dy[..n * d_out].chunks_exact(d_out) {
        for (g, &d) in gb[..d_out].iter_mut().zip(row) {
            *g += d;
        }
    }
    if let Some((dx, cols)) = dx {
        assert!(dx.len() >= n * d_in && cols.end <= d_in);
        if cols.is_empty() {
            return;
        }
        // dx[:, cols] (n×|cols|) = dy (n×d_out) · W[:, cols] (d_out×|cols|).
        let a = Strided::row_major(dy, d_out);
        let width = cols.len();
        let c0 = cols.start;
        dense::gemm(
            n,
            d_out,
            width,
            a,
            &w[c0..],
            d_in,
            &mut dx[c0..],
            d_in,
            Init::Zero,
        );
    }
}

/// A multilayer perceptron `dims[0] → dims[1] → … → dims[last]` (shape only; parameters live in
/// a slice of the flat buffer).
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    pub dims: Vec<usize>,
    pub hidden: Activation,
}

/// Activations kept for the backward pass: `acts[l]` is the output of hidden layer `l`,
/// `[n][dims[l+1]]` row-major.
#[derive(Debug, Default, Clone)]
pub struct MlpTape<T> {
    pub acts: Vec<Vec<T>>,
    /// `deriv[l]`: the activation's derivative at hidden layer `l`, same shape as `acts[l]`.
    pub deriv: Vec<Vec<T>>,
}

impl Mlp {
    pub fn new(dims: Vec<usize>, hidden: Activation) -> Self {
        assert!(dims.len() >= 2);
        Self { dims, hidden }
    }

    pub fn n_layers(&self) -> usize {
        self.dims.len() - 1
    }

    pub fn input_dim(&self) -> usize {
        self.dims[0]
    }

    pub fn output_dim(&self) -> usize {
        *self.dims.last().unwrap_or(&0)
    }

    /// Width of the last hidden layer.
    pub fn last_hidden_dim(&self) -> usize {
        self.dims[self.dims.len() - 2]
    }

    /// Offset of `W_l` in the network's parameter slice; `b_l` follows it.
    pub fn weight_offset(&self, l: usize) -> usize {
        (0..l).map(|i| self.dims[i + 1] * (self.dims[i] + 1)).sum()
    }

    pub fn n_params(&self) -> usize {
        self.weight_offset(self.n_layers())
    }

    fn wb<'a, T>(&self, p: &'a [T], l: usize) -> (&'a [T], &'a [T]) {
        let o = self.weight_offset(l);
        let nw = self.dims[l] * self.dims[l + 1];
        (&p[o..o + nw], &p[o + nw..o + nw + self.dims[l + 1]])
    }

    fn wb_mut<'a, T>(&self, p: &'a mut [T], l: usize) -> (&'a mut [T], &'a mut [T]) {
        let o = self.weight_offset(l);
        let nw = self.dims[l] * self.dims[l + 1];
        let (w, rest) = p[o..].split_at_mut(nw);
        (w, &mut rest[..self.dims[l + 1]])
    }

    /// Geometric (sphere) initialisation (Atzmon & Lipman, SAL 2020; instant-nsr-pl
    /// `VanillaMLP.make_linear` with `sphere_init`): first layer `N(0, √2/√out)` on the first three
    /// inputs (xyz) and 0 elsewhere, hidden layers `N(0, √2/√out)`, last layer
    /// `N(√π/√in, 1e-4)` with bias `−radius`; other biases 0. The SDF starts near `|x| − radius`.
    pub fn init_sphere<R: Rng>(&self, p: &mut [f32], rng: &mut R, radius: f32) {
        let last = self.n_layers() - 1;
        for l in 0..self.n_layers() {
            let (d_in, d_out) = (self.dims[l], self.dims[l + 1]);
            let (w, b) = self.wb_mut(p, l);
            if l == last {
                let nd = Normal::new(std::f32::consts::PI.sqrt() / (d_in as f32).sqrt(), 1e-4)
                    .expect("finite normal");
                w.iter_mut().for_each(|v| *v = nd.sample(rng));
                b.fill(-radius);
            } else {
                let nd = Normal::new(0.0, 2f32.sqrt() / (d_out as f32).sqrt()).expect("normal");
                for o in 0..d_out {
                    for i in 0..d_in {
                        w[o * d_in + i] = if l == 0 && i >= 3 {
                            0.0
                        } else {
                            nd.sample(rng)
                        };
                    }
                }
                b.fill(0.0);
            }
        }
    }

    /// PyTorch `kaiming_uniform_(nonlinearity='relu')` weights, `U(±√(6/in))`, zero biases
    /// (instant-nsr-pl `VanillaMLP` without sphere init).
    pub fn init_kaiming<R: Rng>(&self, p: &mut [f32], rng: &mut R) {
        for l in 0..self.n_layers() {
            let bound = (6.0 / self.dims[l] as f32).sqrt();
            let (w, b) = self.wb_mut(p, l);
            w.iter_mut()
                .for_each(|v| *v = rng.random_range(-bound..bound));
            b.fill(0.0);
        }
    }

    /// Runs all hidden layers on `x [n][dims[0]]`, storing their outputs in `tape`.
    pub fn forward_hidden<T: Real>(&self, p: &[T], x: &[T], n: usize, tape: &mut MlpTape<T>) {
        self.forward_hidden_with(p, x, n, tape, |_, _| {});
    }

    /// [`forward_hidden`](Self::forward_hidden) calling `last(row, h_row)` on each row of the
    /// last hidden layer's output as it is produced (still in registers): the place for cheap
    /// per-row products such as one output channel (`h · W_last[0] + b`).
    pub fn forward_hidden_with<T: Real, F: FnMut(usize, &[T])>(
        &self,
        p: &[T],
        x: &[T],
        n: usize,
        tape: &mut MlpTape<T>,
        mut last: F,
    ) {
        let nh = self.n_layers() - 1;
        tape.acts.resize_with(nh, Vec::new);
        tape.deriv.resize_with(nh, Vec::new);
        for l in 0..nh {
            let (d_in, d_out) = (self.dims[l], self.dims[l + 1]);
            let (w, b) = self.wb(p, l);
            let mut y = std::mem::take(&mut tape.acts[l]);
            y.resize(n * d_out, T::ZERO);
            let mut dv = std::mem::take(&mut tape.deriv[l]);
            dv.resize(n * d_out, T::ZERO);
            {
                let input: &[T] = if l == 0 { x } else { &tape.acts[l - 1] };
                // The activation and its derivative, fused into the product's epilogue.
                let hidden = self.hidden;
                let dvs = &mut dv[..];
                let is_last = l + 1 == nh;
                linear_forward_then(w, b, input, n, d_in, d_out, &mut y, |i, row| {
                    let d = &mut dvs[i * d_out..(i + 1) * d_out];
                    match hidden {
                        Activation::Relu => {
                            for (v, d) in row.iter_mut().zip(d.iter_mut()) {
                                let pos = *v > T::ZERO;
                                *v = if pos { *v } else { T::ZERO };
                                *d = if pos { T::ONE } else { T::ZERO };
                            }
                        }
                        Activation::Softplus { beta } => {
                            let b = T::from_f32(beta);
                            for (v, d) in row.iter_mut().zip(d.iter_mut()) {
                                let (a, s) = T::softplus_and_grad(*v, b);
                                *v = a;
                                *d = s;
                            }
                        }
                    }
                    if is_last {
                        last(i, row);
                    }
                });
            }
            tape.deriv[l] = dv;
            tape.acts[l] = y;
        }
    }

    /// Output channel `c` of the last (linear) layer for one row of the last hidden activation:
    /// `h · W_last[c] + b_last[c]` (for [`forward_hidden_with`](Self::forward_hidden_with)).
    #[inline(always)]
    pub fn output_channel<T: Real>(&self, p: &[T], c: usize, h: &[T]) -> T {
        let l = self.n_layers() - 1;
        let (w, b) = self.wb(p, l);
        let d = self.dims[l];
        let wr = &w[c * d..(c + 1) * d];
        // 16 partial sums (one vector register for f32) instead of one serial FMA chain.
        let mut acc = [T::ZERO; 16];
        let (hc, wc) = (h[..d].chunks_exact(16), wr.chunks_exact(16));
        let (hr, wrr) = (hc.remainder(), wc.remainder());
        for (hh, ww) in hc.zip(wc) {
            for k in 0..16 {
                acc[k] = hh[k].fma(ww[k], acc[k]);
            }
        }
        for (k, (hv, wv)) in hr.iter().zip(wrr).enumerate() {
            acc[k] = hv.fma(*wv, acc[k]);
        }
        let mut s = T::ZERO;
        for v in acc {
            s += v;
        }
        s + b[c]
    }

    /// Last (linear) layer on rows of the last hidden activation `h [n][last_hidden_dim]`,
    /// computing only the first `cols` outputs into `out [n][cols]`.
    pub fn forward_last<T: Real>(&self, p: &[T], h: &[T], n: usize, cols: usize, out: &mut [T]) {
        let l = self.n_layers() - 1;
        let (w, b) = self.wb(p, l);
        linear_forward(w, b, h, n, self.dims[l], cols, out);
    }

    /// Backward of [`forward_last`](Self::forward_last): accumulates parameter gradients into
    /// `g` (the network's gradient slice) and writes `d_h [n][last_hidden_dim]`.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_last<T: Real>(
        &self,
        p: &[T],
        g: &mut [T],
        h: &[T],
        n: usize,
        cols: usize,
        d_out: &[T],
        d_h: &mut [T],
    ) {
        let l = self.n_layers() - 1;
        let (w, _) = self.wb(p, l);
        let d_in = self.dims[l];
        let (gw, gb) = self.wb_mut(g, l);
        linear_backward(w, h, d_out, n, d_in, cols, gw, gb, Some(d_h));
    }

    /// Backward through the hidden layers. `d_h` holds the gradient of the last hidden layer's
    /// output `[n][last_hidden_dim]` and is used as scratch; `scratch` is resized as needed.
    /// Writes `d_x [n][dims[0]]` if given.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_hidden<T: Real>(
        &self,
        p: &[T],
        g: &mut [T],
        x: &[T],
        n: usize,
        tape: &MlpTape<T>,
        d_h: &mut Vec<T>,
        scratch: &mut Vec<T>,
        d_x: Option<&mut [T]>,
    ) {
        let cols = 0..self.dims[0];
        self.backward_hidden_cols(p, g, x, n, tape, d_h, scratch, d_x.map(|d| (d, cols)));
    }

    /// [`backward_hidden`](Self::backward_hidden) writing only the input-gradient columns `cols`
    /// of `d_x [n][dims[0]]` (see [`linear_backward_cols`]).
    #[allow(clippy::too_many_arguments)]
    pub fn backward_hidden_cols<T: Real>(
        &self,
        p: &[T],
        g: &mut [T],
        x: &[T],
        n: usize,
        tape: &MlpTape<T>,
        d_h: &mut Vec<T>,
        scratch: &mut Vec<T>,
        mut d_x: Option<(&mut [T], std::ops::Range<usize>)>,
    ) {
        let nh = self.n_layers() - 1;
        for l in (0..nh).rev() {
            let (d_in, d_out) = (self.dims[l], self.dims[l + 1]);
            for (d, &s) in d_h[..n * d_out].iter_mut().zip(&tape.deriv[l][..n * d_out]) {
                *d *= s;
            }
            let (w, _) = self.wb(p, l);
            let input: &[T] = if l == 0 { x } else { &tape.acts[l - 1] };
            let (gw, gb) = self.wb_mut(g, l);
            if l > 0 {
                scratch.resize(n * d_in, T::ZERO);
                linear_backward(w, input, d_h, n, d_in, d_out, gw, gb, Some(scratch));
                std::mem::swap(d_h, scratch);
            } else {
                let dx = d_x.as_mut().map(|(d, c)| (&mut **d, c.clone()));
                linear_backward_cols(w, input, d_h, n, d_in, d_out, gw, gb, dx);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn gemm_linear_matches_naive() {
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        for &(n, di, d_o) in &[
            (1usize, 3usize, 2usize),
            (17, 35, 64),
            (64, 64, 13),
            (5, 64, 1),
        ] {
            let w: Vec<f64> = (0..di * d_o).map(|_| rng.random_range(-1.0..1.0)).collect();
            let b: Vec<f64> = (0..d_o).map(|_| rng.random_range(-1.0..1.0)).collect();
            let x: Vec<f64> = (0..n * di).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut y1 = vec![0.0; n * d_o];
            let mut y2 = vec![0.0; n * d_o];
            linear_forward(&w, &b, &x, n, di, d_o, &mut y1);
            linear_forward_naive(&w, &b, &x, n, di, d_o, &mut y2);
            let worst = y1
                .iter()
                .zip(&y2)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-12, "({n},{di},{d_o}) diff {worst}");
        }
    }

    /// Full MLP backward (all layers, both activations) against central differences in f64.
    #[test]
    fn mlp_backward_matches_central_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(2);
        // Odd widths (matrixmultiply paths), then the widths the register kernels specialise
        // (16/32/64, padded narrow outputs, the transposed weight gradient of a 35-wide input).
        let cases = [
            (vec![5usize, 7, 6, 3], Activation::Relu),
            (vec![5, 7, 6, 3], Activation::Softplus { beta: 3.0 }),
            (vec![16, 32, 16, 3], Activation::Relu),
            (vec![35, 64, 13], Activation::Softplus { beta: 3.0 }),
        ];
        for (dims, act) in cases {
            let (d0, dl) = (dims[0], *dims.last().unwrap());
            let dh_w = dims[dims.len() - 2];
            let mlp = Mlp::new(dims, act);
            let n = 4;
            let mut p: Vec<f64> = (0..mlp.n_params())
                .map(|_| rng.random_range(-1.0..1.0) / (d0 as f64).sqrt())
                .collect();
            let x: Vec<f64> = (0..n * d0).map(|_| rng.random_range(-1.0..1.0)).collect();
            let wout: Vec<f64> = (0..n * dl).map(|_| rng.random_range(-1.0..1.0)).collect();
            let loss = |p: &[f64], x: &[f64]| -> f64 {
                let mut tape = MlpTape::default();
                mlp.forward_hidden(p, x, n, &mut tape);
                let mut out = vec![0.0; n * dl];
                mlp.forward_last(p, tape.acts.last().unwrap(), n, dl, &mut out);
                out.iter().zip(&wout).map(|(a, b)| a * b).sum()
            };
            let mut tape = MlpTape::default();
            mlp.forward_hidden(&p, &x, n, &mut tape);
            let mut g = vec![0.0; mlp.n_params()];
            let mut dh = vec![0.0; n * dh_w];
            mlp.backward_last(&p, &mut g, tape.acts.last().unwrap(), n, dl, &wout, &mut dh);
            let mut dx = vec![0.0; n * d0];
            let mut scratch = Vec::new();
            mlp.backward_hidden(
                &p,
                &mut g,
                &x,
                n,
                &tape,
                &mut dh,
                &mut scratch,
                Some(&mut dx),
            );
            let h = 1e-6;
            let mut fails = Vec::new();
            for i in 0..p.len() {
                let o = p[i];
                p[i] = o + h;
                let lp = loss(&p, &x);
                p[i] = o - h;
                let lm = loss(&p, &x);
                p[i] = o;
                let fd = (lp - lm) / (2.0 * h);
                if (fd - g[i]).abs() > 1e-6 + 1e-5 * fd.abs() {
                    fails.push(format!("{act:?} param {i}: analytic {} fd {fd}", g[i]));
                }
            }
            let mut xx = x.clone();
            for i in 0..xx.len() {
                let o = xx[i];
                xx[i] = o + h;
                let lp = loss(&p, &xx);
                xx[i] = o - h;
                let lm = loss(&p, &xx);
                xx[i] = o;
                let fd = (lp - lm) / (2.0 * h);
                if (fd - dx[i]).abs() > 1e-6 + 1e-5 * fd.abs() {
                    fails.push(format!("{act:?} input {i}: analytic {} fd {fd}", dx[i]));
                }
            }
            assert!(fails.is_empty(), "{}", fails.join("\n"));
        }
    }

    #[test]
    fn sphere_init_gives_sphere_sdf() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let mlp = Mlp::new(vec![35, 64, 13], Activation::Softplus { beta: 100.0 });
        let mut p = vec![0f32; mlp.n_params()];
        mlp.init_sphere(&mut p, &mut rng, 0.5);
        let p64: Vec<f64> = p.iter().map(|&v| v as f64).collect();
        // Along several directions the SDF at radius ρ should be close to ρ − 0.5 (in
        // expectation; we allow the spread of a random 64-wide layer).
        let mut worst = 0.0f64;
        for &(rho, dir) in &[
            (0.2, [1.0, 0.0, 0.0]),
            (0.5, [0.0, 0.6, 0.8]),
            (0.8, [0.0, 0.0, -1.0]),
        ] {
            let mut x = vec![0.0; 35];
            for d in 0..3 {
                x[d] = rho * dir[d];
            }
            let mut tape = MlpTape::default();
            mlp.forward_hidden(&p64, &x, 1, &mut tape);
            let mut out = vec![0.0; 13];
            mlp.forward_last(&p64, &tape.acts[0], 1, 13, &mut out);
            worst = worst.max((out[0] - (rho - 0.5)).abs());
        }
        assert!(worst < 0.25, "sphere init SDF off by {worst}");
    }
}
