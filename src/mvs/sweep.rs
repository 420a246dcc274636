//! Step 1 of the module doc of [`super`]: the plane sweep.

use super::{box_sum, integral, MvsConfig, View};
use nalgebra::Vector3;

pub(super) fn sweep_view(cfg: &MvsConfig, views: &[View], i: usize, srcs: &[usize]) -> Vec<f32> {
    let vi = &views[i];
    let (w, h, hf) = (vi.w, vi.h, cfg.window_half);
    let mut zmap = vec![f32::NAN; w * h];
    // The mask's bounding box, widened by the window.
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for (k, _) in vi.mask.iter().enumerate().filter(|m| *m.1) {
        let (x, y) = (k % w, k / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    if x0 >= x1 || srcs.len() < cfg.top_k {
        return zmap;
    }
    let (bx0, by0) = (x0.saturating_sub(hf), y0.saturating_sub(hf));
    let (bx1, by1) = ((x1 + hf).min(w), (y1 + hf).min(h));
    let (bw, bh) = (bx1 - bx0, by1 - by0);
    let a: Vec<f64> = (0..bw * bh)
        .map(|k| vi.grey[(by0 + k / bw) * w + bx0 + k % bw] as f64)
        .collect();
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    let a_bad = integral(bw, bh, |k| if a[k].is_finite() { 0.0 } else { 1.0 });
    let sa = integral(bw, bh, |k| finite(a[k]));
    let saa = integral(bw, bh, |k| finite(a[k]) * finite(a[k]));
    // Camera depths of the bounding sphere.
    let zc = vi.r.row(2).transpose().dot(&(-vi.c));
    let rad = cfg.depth_radius as f64;
    let (zn, zf) = ((zc - rad).max(1e-3 * rad), zc + rad);
    let dz = (zf - zn) / cfg.planes as f64;
    // Per source: `A·p` per pixel and `b`, so that pixel `p` at depth `z` maps to `z·A·p + b`.
    let setups: Vec<(Vec<Vector3<f64>>, Vector3<f64>)> = srcs
        .iter()
        .map(|&j| {
            let (am, b) = vi.warp_to(&views[j]);
            let ap = (0..bw * bh)
                .map(|k| {
                    let (x, y) = ((bx0 + k % bw) as f64 + 0.5, (by0 + k / bw) as f64 + 0.5);
                    am * Vector3::new(x, y, 1.0)
                })
                .collect();
            (ap, b)
        })
        .collect();
    let nwin = ((2 * hf + 1) * (2 * hf + 1)) as f64;
    let min_var = (cfg.min_std as f64).powi(2) * nwin;
    // The masked pixels whose window lies inside the box.
    let pix: Vec<(usize, usize)> = (y0.max(by0 + hf)..y1.min(by1 - hf))
        .flat_map(|y| (x0.max(bx0 + hf)..x1.min(bx1 - hf)).map(move |x| (x, y)))
        .filter(|&(x, y)| vi.mask[y * w + x])
        .collect();
    let np = pix.len();
    let ns = srcs.len();
    // Per pixel, streamed over the planes (no `pixels × planes` table: 1 GB for a 1600 × 1200
    // view): the best cost, its plane, the costs of the planes either side, and the last cost.
    let mut best = vec![(f32::INFINITY, usize::MAX, f32::NAN, f32::NAN); np];
    let mut prev = vec![f32::NAN; np];
    let mut per = vec![f32::NAN; np * ns];
    let mut wv = vec![0f64; bw * bh];
    for pl in 0..cfg.planes {
        let zp = zn + (pl as f64 + 0.5) * dz;
        for (s, (ap, b)) in setups.iter().enumerate() {
            let vj = &views[srcs[s]];
            for (k, out) in wv.iter_mut().enumerate() {
                let hh = ap[k] * zp + b;
                *out = if hh.z > 1e-9 {
                    vj.bilinear(hh.x / hh.z, hh.y / hh.z) as f64
                } else {
                    f64::NAN
                };
            }
            let bad = integral(bw, bh, |k| if wv[k].is_finite() { 0.0 } else { 1.0 });
            let sb = integral(bw, bh, |k| finite(wv[k]));
            let sbb = integral(bw, bh, |k| finite(wv[k]) * finite(wv[k]));
            let sab = integral(bw, bh, |k| finite(wv[k]) * finite(a[k]));
            for (q, &(x, y)) in pix.iter().enumerate() {
                let (lx, ly) = (x - bx0, y - by0);
                let (xa, ya, xb, yb) = (lx - hf, ly - hf, lx + hf + 1, ly + hf + 1);
                let c = if box_sum(&bad, bw, xa, ya, xb, yb) > 0.5
                    || box_sum(&a_bad, bw, xa, ya, xb, yb) > 0.5
                {
                    f32::NAN
                } else {
                    let s_a = box_sum(&sa, bw, xa, ya, xb, yb);
                    let s_b = box_sum(&sb, bw, xa, ya, xb, yb);
                    let va = box_sum(&saa, bw, xa, ya, xb, yb) - s_a * s_a / nwin;
                    let vb = box_sum(&sbb, bw, xa, ya, xb, yb) - s_b * s_b / nwin;
                    if va < min_var || vb < min_var || va <= 0.0 || vb <= 0.0 {
                        f32::NAN
                    } else {
                        let cov = box_sum(&sab, bw, xa, ya, xb, yb) - s_a * s_b / nwin;
                        (1.0 - cov / (va * vb).sqrt()) as f32
                    }
                };
                per[q * ns + s] = c;
            }
        }
        let mut cs = Vec::with_capacity(ns);
        for q in 0..np {
            cs.clear();
            cs.extend(
                per[q * ns..(q + 1) * ns]
                    .iter()
                    .copied()
                    .filter(|c| c.is_finite()),
            );
            let c = top_k_mean(&mut cs, cfg.top_k);
            let b = &mut best[q];
            if c < b.0 {
                *b = (c, pl, prev[q], f32::NAN);
            } else if pl > 0 && b.1 == pl - 1 {
                b.3 = c;
            }
            prev[q] = c;
        }
    }
    for (q, &(x, y)) in pix.iter().enumerate() {
        let (bc, bp, cm, cp) = best[q];
        if bp == usize::MAX || bc > cfg.max_cost {
            continue;
        }
        let mut off = 0.0;
        if bp > 0 && bp + 1 < cfg.planes {
            let den = cm - 2.0 * bc + cp;
            if cm.is_finite() && cp.is_finite() && den > 1e-6 {
                off = (0.5 * (cm - cp) / den).clamp(-0.5, 0.5) as f64;
            }
        }
        zmap[y * w + x] = (zn + (bp as f64 + 0.5 + off) * dz) as f32;
    }
    zmap
}

/// The mean of the `k` smallest of `costs` (sorted in place): a plane's cost over its sources
/// (step 1). NaN when `costs` holds fewer than `k`.
pub(super) fn top_k_mean(costs: &mut [f32], k: usize) -> f32 {
    if costs.len() < k {
        return f32::NAN;
    }
    costs.sort_by(|a, b| a.total_cmp(b));
    costs[..k].iter().sum::<f32>() / k as f32
}
