//! The rays' gradient phase of a training step (pose refinement's input): `(∂L/∂o, ∂L/∂d)` of
//! each ray from the buffers the other phases of `step.rs` leave in the chunk's scratch.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::super::neus::{NeusModel, RAY_GRAD_SKIP};
use super::super::workspace::{tap_rows, Groups, Scratch};
use super::{Chunk, StepCtx};
use crate::field::hashgrid::fd_point;
use crate::field::sh::{sh4_backward, SH_DIM};
use crate::field::Real;

impl NeusModel {
    /// Each ray's `(∂L/∂o, ∂L/∂d)` into `ctx.ray_grads` (nothing without it), the sample
    /// distances `t` held fixed. Every point where the SDF network ran (the sample `x = o + t·d`
    /// and its taps, which move with `x` except along an axis where the box clamps them) adds
    /// its encoding's input gradient ([`crate::field::HashGrid::encode_input_vjp`] of its row of
    /// `d_encoding`) to `∂L/∂x`; then `∂L/∂o = Σ ∂L/∂x` and `∂L/∂d = Σ (t·∂L/∂x + ∂L/∂d|direct)`,
    /// the direct part through the colour network's direction encoding and NeuS's `cos(d, n)`.
    pub(super) fn ray_backward<T: Real>(
        &self,
        p: &Groups<T>,
        ctx: &StepCtx,
        c: &Chunk<T>,
        sc: &Scratch<T>,
    ) {
        let Some(out) = ctx.ray_grads else {
            return;
        };
        let (n, d, fdim, dc) = (c.n, c.d, c.fdim, c.dc);
        let view = T::from_f32(ctx.sched.view_dependence);
        let spare = (n + sc.tap_off[n]) * d;
        let mut d_sh = [T::ZERO; SH_DIM];
        let mut i = 0;
        for r in c.r0..c.r1 {
            let mut acc = [0.0f64; 6];
            let range = ctx.samples.range(r);
            if out[r][0].load(std::sync::atomic::Ordering::Relaxed) == RAY_GRAD_SKIP {
                // Not wanted: written as zero, its samples passed over.
                i += range.len();
                for cell in &out[r] {
                    cell.store(0f64.to_bits(), std::sync::atomic::Ordering::Relaxed);
                }
                continue;
            }
            for _ in range {
                let (x, taps) = (sc.points[i], sc.tap_points[i]);
                let (rows, _) = tap_rows(i, n, d, &sc.tap_off, &sc.tap_sides);
                let mut gx = [T::ZERO; 3];
                for (q, &row) in rows.iter().enumerate() {
                    if q > 0 && row == spare {
                        continue;
                    }
                    let pt = fd_point(x, taps, q);
                    let gp = self.grid.encode_input_vjp(
                        p.hash,
                        pt,
                        c.radius,
                        c.active,
                        &sc.d_encoding[row..row + d],
                    );
                    // A tap clamped to the box's face stays there when the sample moves along
                    // the tap's axis.
                    let pinned = (q > 0)
                        .then(|| (q - 1) / 2)
                        .filter(|&a| pt[a] != x[a] && (pt[a] >= c.radius || pt[a] <= -c.radius));
                    for k in 0..3 {
                        if pinned != Some(k) {
                            gx[k] += gp[k];
                        }
                    }
                }
                let dci = &sc.d_color_in[i * dc..(i + 1) * dc];
                d_sh.copy_from_slice(&dci[fdim..fdim + SH_DIM]);
                for v in &mut d_sh[1..] {
                    *v *= view;
                }
                let gd = sh4_backward(sc.dirs[i], &d_sh);
                let dcos = sc.d_alpha[i] * sc.alpha_grad[i].d_cos;
                let t = sc.ray_t[i];
                for k in 0..3 {
                    acc[k] += gx[k].to_f64();
                    acc[3 + k] += (t * gx[k] + gd[k] + dcos * sc.normal[i][k]).to_f64();
                }
                i += 1;
            }
            for (cell, v) in out[r].iter().zip(acc) {
                cell.store(v.to_bits(), std::sync::atomic::Ordering::Relaxed);
            }
        }
    }
}
