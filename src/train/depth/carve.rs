//! The depth loss's geometry: which rays it looks at, where the field's surface lies along them
//! (a first-crossing search), and the hinge-plus-surface loss on a fixed plan of points with its
//! gradient.

use crate::field::Real;
use crate::render::rays::ray_aabb;
use crate::render::NeusModel;
use crate::train::data::Batch;

/// One ray of the depth loss's plan (`super::DepthPrior::plan`); points in the normalised frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CarvedRay {
    /// The surface point's distance `t*` along the unit ray.
    pub t: f64,
    /// The stereo depth's distance `t_b` along the ray.
    pub t_b: f64,
    /// The carved span's points and the SDF the hinge asks for at each.
    pub free: Vec<([f64; 3], f64)>,
    /// Points the span held before other views confirmed or vetoed them
    /// (`DepthConfig::confirm_views`, `DepthConfig::veto_band`; `free.len()` without either):
    /// the hinge's mean over the ray divides by it, so points left out do not make the others
    /// pull harder.
    pub span: usize,
    /// The point at `t_b`.
    pub surface: [f64; 3],
    /// Whether the surface term applies at it (other views agree with the depth, and none sees
    /// past it; always without `DepthConfig::confirm_views` and `DepthConfig::veto_band`).
    pub pull: bool,
}

/// The loss on fixed points (the plan's positions are held): `L = weight · mean over rays of
/// (sum over the ray's free points of max(0, τ − f) / span + [pull]·surface_weight·|f(x_b)|)`;
/// `∂L/∂θ` added into `grads` (SDF network and hash grid only). `sdf` evaluates the field at
/// points in the precision of `params`. Returns `L` (0 for an empty plan).
#[allow(clippy::too_many_arguments)]
pub fn carve_loss_grad<T: Real>(
    weight: f32,
    surface_weight: f32,
    model: &NeusModel,
    params: &[T],
    sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
    plan: &[CarvedRay],
    active: usize,
    grads: &mut [T],
) -> f64 {
    if plan.is_empty() {
        return 0.0;
    }
    let mut pts: Vec<[f64; 3]> = Vec::new();
    for c in plan {
        pts.extend(c.free.iter().map(|(x, _)| *x));
        pts.push(c.surface);
    }
    let f = sdf(&pts);
    let w = weight as f64 / plan.len() as f64;
    let mut loss = 0.0;
    let mut wts = Vec::with_capacity(pts.len());
    let mut i = 0;
    for c in plan {
        let m = w / c.span.max(1) as f64;
        for &(_, tau) in &c.free {
            let fv = f[i];
            i += 1;
            if fv < tau {
                loss += m * (tau - fv);
                wts.push(T::from_f64(-m));
            } else {
                wts.push(T::ZERO);
            }
        }
        let fv = f[i];
        i += 1;
        let ms = if c.pull {
            w * surface_weight as f64
        } else {
            0.0
        };
        loss += ms * fv.abs();
        wts.push(T::from_f64(ms * fv.signum()));
    }
    let pts: Vec<[T; 3]> = pts.iter().map(|x| x.map(T::from_f64)).collect();
    model.sdf_weighted_grad(params, &pts, &wts, active, grads);
    loss
}

/// The first `count` rays of `batch` inside the mask (all of them without masks), as
/// `(view, [x, y])`.
pub(crate) fn masked_rays(batch: &Batch, count: usize) -> Vec<(usize, [u32; 2])> {
    (0..batch.len())
        .filter(|&i| batch.mask.get(i).is_none_or(|&m| m >= 0.5))
        .take(count)
        .map(|i| (batch.views[i] as usize, batch.pixels[i]))
        .collect()
}

/// The field's SDF (channel 0, `active` hash levels) at f64 points, evaluated in f32.
pub(crate) fn sdf_f64<'a>(
    model: &'a NeusModel,
    params: &'a [f32],
    active: usize,
) -> impl Fn(&[[f64; 3]]) -> Vec<f64> + 'a {
    move |pts: &[[f64; 3]]| -> Vec<f64> {
        let p32: Vec<[f32; 3]> = pts.iter().map(|p| p.map(|v| v as f32)).collect();
        model
            .sdf(params, &p32, active)
            .into_iter()
            .map(|v| v as f64)
            .collect()
    }
}

/// A ray's first surface crossing: distance `t` along the unit direction, and the SDF gradient
/// there (central differences).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Hit {
    /// Distance along the unit ray.
    pub(crate) t: f64,
    /// The SDF gradient there (central differences).
    pub(crate) grad: [f64; 3],
}

/// The first `+ → −` crossing of `sdf` along each ray `(o, d)` (unit `d`) inside the box
/// `[-r, r]³`: `samples` evenly spaced values over the ray's span of the box, then `refine`
/// Illinois steps on the bracket, then the gradient by central differences of step `eps`.
/// `sdf` evaluates a batch of points. `None` for a ray that misses the box, starts inside
/// (`f < 0` at its first sample) or finds no crossing.
pub(crate) fn surface_hits(
    sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
    rays: &[([f64; 3], [f64; 3])],
    r: f32,
    samples: usize,
    refine: usize,
    eps: f64,
) -> Vec<Option<Hit>> {
    let at = |(o, d): ([f64; 3], [f64; 3]), t: f64| [0, 1, 2].map(|q| o[q] + t * d[q]);
    let spans: Vec<Option<(f64, f64)>> = rays
        .iter()
        .map(|&(o, d)| {
            ray_aabb(o.map(|v| v as f32), d.map(|v| v as f32), r).map(|(a, b)| (a as f64, b as f64))
        })
        .collect();
    let mut pts = Vec::with_capacity(rays.len() * samples);
    for (k, span) in spans.iter().enumerate() {
        if let Some((t0, t1)) = *span {
            let dt = (t1 - t0) / samples as f64;
            for s in 0..samples {
                pts.push(at(rays[k], t0 + (s as f64 + 0.5) * dt));
            }
        }
    }
    let f = sdf(&pts);
    // Brackets `(t_a, f_a, t_b, f_b)` with `f_a > 0 ≥ f_b`.
    let mut brackets: Vec<Option<(f64, f64, f64, f64)>> = Vec::with_capacity(rays.len());
    let mut off = 0;
    for span in &spans {
        let Some((t0, t1)) = *span else {
            brackets.push(None);
            continue;
        };
        let dt = (t1 - t0) / samples as f64;
        let fs = &f[off..off + samples];
        off += samples;
        let b = if fs[0] < 0.0 {
            None
        } else {
            (0..samples - 1)
                .find(|&s| fs[s] > 0.0 && fs[s + 1] <= 0.0)
                .map(|s| {
                    let ta = t0 + (s as f64 + 0.5) * dt;
                    (ta, fs[s], ta + dt, fs[s + 1])
                })
        };
        brackets.push(b);
    }
    // Illinois: the regula-falsi point, halving the kept end's value when an end is kept twice.
    let mut side = vec![0i8; rays.len()];
    for _ in 0..refine {
        let live: Vec<usize> = (0..rays.len())
            .filter(|&k| brackets[k].is_some_and(|b| b.3 < 0.0))
            .collect();
        if live.is_empty() {
            break;
        }
        let ts: Vec<f64> = live
            .iter()
            .map(|&k| {
                let (ta, fa, tb, fb) = brackets[k].expect("live");
                ta + (tb - ta) * fa / (fa - fb)
            })
            .collect();
        let p: Vec<[f64; 3]> = live
            .iter()
            .zip(&ts)
            .map(|(&k, &t)| at(rays[k], t))
            .collect();
        let fm = sdf(&p);
        for ((&k, &t), &v) in live.iter().zip(&ts).zip(&fm) {
            let b = brackets[k].as_mut().expect("live");
            if v > 0.0 {
                *b = (t, v, b.2, if side[k] == 1 { b.3 * 0.5 } else { b.3 });
                side[k] = 1;
            } else {
                *b = (b.0, if side[k] == -1 { b.1 * 0.5 } else { b.1 }, t, v);
                side[k] = -1;
            }
        }
    }
    // The crossing: the last regula-falsi point of the bracket (exact when `f_b = 0`).
    let ts: Vec<Option<f64>> = brackets
        .iter()
        .map(|b| b.map(|(ta, fa, tb, fb)| ta + (tb - ta) * fa / (fa - fb)))
        .collect();
    let mut taps = Vec::new();
    for (k, t) in ts.iter().enumerate() {
        if let Some(t) = *t {
            let x = at(rays[k], t);
            for q in 0..3 {
                for s in [1.0, -1.0] {
                    let mut y = x;
                    y[q] += s * eps;
                    taps.push(y);
                }
            }
        }
    }
    let ft = sdf(&taps);
    let mut i = 0;
    ts.iter()
        .map(|t| {
            t.map(|t| {
                let g = [0, 1, 2].map(|q| (ft[i + 2 * q] - ft[i + 2 * q + 1]) / (2.0 * eps));
                i += 6;
                Hit { t, grad: g }
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_search_finds_the_first_crossing() {
        // Two spheres along the x axis: the ray from −3 meets the nearer one first.
        let sdf = |pts: &[[f64; 3]]| -> Vec<f64> {
            pts.iter()
                .map(|p| {
                    let a = ((p[0] + 0.5).powi(2) + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.2;
                    let b = ((p[0] - 0.5).powi(2) + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.2;
                    a.min(b)
                })
                .collect()
        };
        let rays = [
            ([-3.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            ([-3.0, 0.1, 0.0], [1.0, 0.0, 0.0]),
            ([-3.0, 0.9, 0.0], [1.0, 0.0, 0.0]),
            ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ];
        let hits = surface_hits(&sdf, &rays, 1.0, 64, 20, 1e-5);
        let h0 = hits[0].expect("hit");
        assert!((h0.t - 2.3).abs() < 1e-9, "{}", h0.t);
        assert!((h0.grad[0] + 1.0).abs() < 1e-6);
        let h1 = hits[1].expect("hit");
        let want = 2.5 - (0.04f64 - 0.01).sqrt();
        assert!((h1.t - want).abs() < 1e-8, "{} vs {want}", h1.t);
        assert!(hits[2].is_none(), "a miss");
        assert!(hits[3].is_none(), "outside at the start but never crossing");
        let inside = surface_hits(
            &sdf,
            &[([-0.5, 0.0, 0.0], [1.0, 0.0, 0.0])],
            1.0,
            64,
            4,
            1e-5,
        );
        assert!(inside[0].is_none(), "starts inside");
    }
}
