//! Losses on the SDF channel at points, and their gradients: the regression onto target values
//! that the visual-hull initialisation (`train::hull`) minimises before the first rendering
//! step, and a weighted sum of SDF values (the depth prior's loss, `train::depth`).
//!
//! The regression is the mean absolute error `L = (1/n) Σ_i |f(x_i) − t_i|` of the SDF network's
//! channel 0 at points `x_i` (normalised space, inside the box `[-r, r]³`) against targets `t_i`
//! (normalised units). L1, as IGR and DeepSDF fit signed distances (DeepSDF §4, clamped L1): a
//! few far-off targets do not dominate the near-surface ones. The gradients flow through the SDF
//! network and the hash grid only; no other group is touched.

use super::workspace::{split, split_mut};
use super::NeusModel;
use crate::field::mlp::MlpTape;
use crate::field::Real;

impl NeusModel {
    /// `L = (1/n) Σ |f(x_i) − t_i|` over `points [n][3]` and `targets [n]`, with `active` hash
    /// levels; adds `∂L/∂θ` into `grads` (same layout as `params`, only the `hash_grid` and
    /// `sdf_mlp` groups are written). Returns `L` (0 for no points). Single-threaded; callers
    /// keep `n` to a few thousand points.
    ///
    /// Where `f(x_i) = t_i` exactly the subgradient 0 is used.
    pub fn sdf_fit_loss_grad<T: Real>(
        &self,
        params: &[T],
        points: &[[T; 3]],
        targets: &[T],
        active: usize,
        grads: &mut [T],
    ) -> f64 {
        assert_eq!(points.len(), targets.len(), "one target per point");
        let inv_n = T::from_f64(1.0 / points.len().max(1) as f64);
        self.sdf_point_loss_grad(params, points, active, grads, |i, f| {
            let e = f - targets[i];
            let d = if e > T::ZERO {
                inv_n
            } else if e < T::ZERO {
                T::ZERO - inv_n
            } else {
                T::ZERO
            };
            (e.abs().to_f64(), d)
        }) / points.len().max(1) as f64
    }

    /// Adds `Σ_i w_i·∂f(x_i)/∂θ` into `grads` for `points [n][3]` and weights `w [n]`, with
    /// `active` hash levels (only the `hash_grid` and `sdf_mlp` groups are written), and returns
    /// the SDF values `f(x_i)` (normalised units). The multi-view prior (`train::multiview`)
    /// moves surface points through it by implicit differentiation. Single-threaded.
    pub fn sdf_weighted_grad<T: Real>(
        &self,
        params: &[T],
        points: &[[T; 3]],
        weights: &[T],
        active: usize,
        grads: &mut [T],
    ) -> Vec<f64> {
        assert_eq!(points.len(), weights.len(), "one weight per point");
        let mut f = vec![0.0; points.len()];
        self.sdf_point_loss_grad(params, points, active, grads, |i, v| {
            f[i] = v.to_f64();
            (0.0, weights[i])
        });
        f
    }

    /// The shared core: evaluates channel 0 of the SDF network at `points`, asks `per_point(i,
    /// f_i)` for the point's loss term and `∂L/∂f_i`, back-propagates those into `grads` and
    /// returns the sum of the terms. Single-threaded.
    fn sdf_point_loss_grad<T: Real>(
        &self,
        params: &[T],
        points: &[[T; 3]],
        active: usize,
        grads: &mut [T],
        mut per_point: impl FnMut(usize, T) -> (f64, T),
    ) -> f64 {
        assert_eq!(params.len(), self.n_params());
        assert_eq!(grads.len(), self.n_params());
        let n = points.len();
        if n == 0 {
            return 0.0;
        }
        let p = split(&self.layout, params);
        let d = self.grid.output_dim();
        let wh = self.sdf_mlp.last_hidden_dim();
        let r = T::from_f32(self.config.render.radius);
        let mut enc = vec![T::ZERO; n * d];
        self.grid
            .encode_batch(p.hash, points, r, active, &mut enc, d);
        let mut tape = MlpTape::default();
        let mut d_f = vec![T::ZERO; n];
        let mut loss = 0f64;
        self.sdf_mlp
            .forward_hidden_with(p.sdf, &enc, n, &mut tape, |i, h| {
                let (l, d) = per_point(i, self.sdf_mlp.output_channel(p.sdf, 0, h));
                loss += l;
                d_f[i] = d;
            });
        let g = split_mut(&self.layout, grads);
        let mut d_h = vec![T::ZERO; n * wh];
        {
            let h = tape
                .acts
                .last()
                .expect("the SDF network has a hidden layer");
            self.sdf_mlp
                .backward_last(p.sdf, g.sdf, &h[..n * wh], n, 1, &d_f, &mut d_h);
        }
        let mut d_enc = vec![T::ZERO; n * d];
        let mut work = Vec::new();
        self.sdf_mlp.backward_hidden_cols(
            p.sdf,
            g.sdf,
            &enc,
            n,
            &tape,
            &mut d_h,
            &mut work,
            Some((&mut d_enc, self.grid.xyz_dim()..d)),
        );
        for (i, x) in points.iter().enumerate() {
            self.grid
                .encode_backward(*x, r, active, &d_enc[i * d..(i + 1) * d], g.hash);
        }
        loss
    }
}
