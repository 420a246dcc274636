//! A per-view rigid correction of a camera's pose, and its gradient: the building block of pose
//! refinement (BARF, Lin et al. 2021; NeRF−−, Wang et al. 2021; nerfstudio's camera optimizer,
//! `nerfstudio/cameras/camera_optimizers.py`, whose `SO3xR3` mode parametrises the correction the
//! same way: an so(3) vector and a translation, zero at the start).
//!
//! Convention. The correction acts in the camera's own frame: the corrected camera-to-world is
//! `C2W · [R(ω) | t]`, so with `C` the camera-to-world rotation (columns: the camera's x, y, z
//! axes in world coordinates), a ray with origin `o` and direction `d` becomes
//! `o' = o + C t` and `d' = C R(ω) Cᵀ d`. Rotating about the camera's centre keeps the centre
//! where it was and leaves a small rotation nearly independent of the translation; `t` is in the
//! frame's length unit (the normalised frame's, where the object fills the unit sphere).
//! `R(ω)` is the exponential map of SO(3) (Rodrigues' formula).
//!
//! The gradient follows Solà, Deray and Atchuthan, "A micro Lie theory for state estimation in
//! robotics" (2018), eq. 143: `∂(R(ω) v)/∂ω = −R(ω) [v]× J_r(ω)`, with the right Jacobian
//! `J_r(ω) = I − (1 − cos θ)/θ² [ω]× + (θ − sin θ)/θ³ [ω]×²`, `θ = |ω|` (its series near 0).

use nalgebra::{Matrix3, Vector3};

/// The skew-symmetric matrix `[v]×` with `[v]× u = v × u`.
fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `R(ω)`, the rotation by `|ω|` radians about `ω/|ω|` (identity at 0).
pub fn exp_so3(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let k = hat(w);
    // sin θ/θ and (1 − cos θ)/θ², by their series below θ² = 1e-8 (exact to f64 there).
    let (a, b) = if t2 < 1e-8 {
        (1.0 - t2 / 6.0, 0.5 - t2 / 24.0)
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The right Jacobian `J_r(ω)` of SO(3).
fn right_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let k = hat(w);
    let (b, c) = if t2 < 1e-8 {
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let t = t2.sqrt();
        ((1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    Matrix3::identity() - k * b + k * k * c
}

/// One view's correction: `omega` (so(3), radians) and `t` (camera frame, frame length unit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseCorrection {
    pub omega: Vector3<f64>,
    pub t: Vector3<f64>,
}

/// The gradient of a loss with respect to a [`PoseCorrection`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseGrad {
    pub omega: Vector3<f64>,
    pub t: Vector3<f64>,
}

impl PoseCorrection {
    /// The corrected ray `(o', d')` of a ray `(o, d)` of a camera whose camera-to-world rotation
    /// is `c`. `|d'| = |d|`.
    pub fn apply(
        &self,
        c: &Matrix3<f64>,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let r = exp_so3(&self.omega);
        (o + c * self.t, c * (r * (c.transpose() * d)))
    }

    /// Backward of [`apply`](Self::apply): the loss's gradients `g_o`, `g_d` with respect to the
    /// corrected origin and direction, turned into the gradient with respect to `ω` and `t`.
    pub fn backward(
        &self,
        c: &Matrix3<f64>,
        d: &Vector3<f64>,
        g_o: &Vector3<f64>,
        g_d: &Vector3<f64>,
    ) -> PoseGrad {
        let ct = c.transpose();
        let v = ct * d;
        // d' = C R v: ∂d'/∂ω = C · (−R [v]× J_r).
        let jac = -exp_so3(&self.omega) * hat(&v) * right_jacobian(&self.omega);
        PoseGrad {
            omega: jac.transpose() * (ct * g_d),
            t: ct * g_o,
        }
    }
}

/// A camera-frame direction `v` (`v.z > 0`, any length) as the same pixel casts it when the
/// camera's focal lengths are multiplied by `e^φ` (principal point and skew ratio kept): the
/// pixel's normalised coordinates `(v.x/v.z, v.y/v.z)` shrink by `e^−φ`. Returns the unit
/// direction. NeRF−− (Wang et al. 2021) learns the focal lengths with the field the same way,
/// through the rays; a log scale keeps the focal positive and its steps relative.
pub fn apply_focal(phi: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let s = (-phi).exp() / v.z;
    Vector3::new(v.x * s, v.y * s, 1.0).normalize()
}

/// Backward of [`apply_focal`]: the gradient `g` of a loss with respect to its output, turned
/// into the gradient with respect to `φ`.
pub fn focal_backward(phi: f64, v: &Vector3<f64>, g: &Vector3<f64>) -> f64 {
    let s = (-phi).exp() / v.z;
    let w = Vector3::new(v.x * s, v.y * s, 1.0);
    let n = w.norm();
    let u = w / n;
    // ∂w/∂φ = (−w.x, −w.y, 0); ∂(w/|w|)/∂w = (I − u uᵀ)/|w|.
    let dw = Vector3::new(-w.x, -w.y, 0.0);
    (dw - u * u.dot(&dw)).dot(g) / n
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn rand_vec(rng: &mut Pcg64Mcg, s: f64) -> Vector3<f64> {
        if s == 0.0 {
            return Vector3::zeros();
        }
        Vector3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        )
    }

    #[test]
    fn the_exponential_map_is_a_rotation_and_matches_the_axis_angle() {
        let w = Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let r = exp_so3(&w);
        let x = r * Vector3::x();
        assert!((x - Vector3::y()).norm() < 1e-12, "{x}");
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        for s in [1e-9, 1e-5, 0.1, 2.0] {
            let r = exp_so3(&rand_vec(&mut rng, s));
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
    }

    /// Central differences in f64 of a scalar loss `⟨a, o'⟩ + ⟨b, d'⟩` against the analytic
    /// gradient, at corrections from 1e-9 rad (the series branch) to 1.5 rad.
    #[test]
    fn the_pose_gradient_matches_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(9);
        for (trial, s) in [0.0, 1e-9, 1e-3, 0.05, 0.5, 1.5]
            .iter()
            .cycle()
            .take(60)
            .enumerate()
        {
            let c = exp_so3(&rand_vec(&mut rng, 3.0));
            let o = rand_vec(&mut rng, 3.0);
            let d = rand_vec(&mut rng, 1.0).normalize();
            let (a, b) = (rand_vec(&mut rng, 1.0), rand_vec(&mut rng, 1.0));
            let p = PoseCorrection {
                omega: rand_vec(&mut rng, *s),
                t: rand_vec(&mut rng, *s),
            };
            let loss = |q: &PoseCorrection| {
                let (o2, d2) = q.apply(&c, &o, &d);
                a.dot(&o2) + b.dot(&d2)
            };
            let g = p.backward(&c, &d, &a, &b);
            let h = 1e-6;
            for k in 0..3 {
                for (which, analytic) in [(0, g.omega[k]), (1, g.t[k])] {
                    let (mut qp, mut qm) = (p, p);
                    if which == 0 {
                        qp.omega[k] += h;
                        qm.omega[k] -= h;
                    } else {
                        qp.t[k] += h;
                        qm.t[k] -= h;
                    }
                    let fd = (loss(&qp) - loss(&qm)) / (2.0 * h);
                    assert!(
                        (analytic - fd).abs() < 1e-7 * (1.0 + fd.abs()),
                        "trial {trial}, |ω| ~ {s}, {} {k}: {analytic} vs {fd}",
                        ["ω", "t"][which]
                    );
                }
            }
        }
    }

    /// The focal scale's gradient against central differences in f64, from a tenth of a percent
    /// to a third of the focal, on directions across a wide field of view; zero is the
    /// identity, and a larger focal narrows every ray towards the axis.
    #[test]
    fn the_focal_gradient_matches_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        for trial in 0..40 {
            let phi = [0.0, 1e-3, -0.05, 0.3][trial % 4];
            let v = Vector3::new(
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.6..0.6),
                rng.random_range(0.5..2.0),
            );
            let g = rand_vec(&mut rng, 1.0);
            let loss = |p: f64| g.dot(&apply_focal(p, &v));
            let h = 1e-6;
            let fd = (loss(phi + h) - loss(phi - h)) / (2.0 * h);
            let an = focal_backward(phi, &v, &g);
            assert!(
                (an - fd).abs() < 1e-8 * (1.0 + fd.abs()),
                "trial {trial}, φ {phi}: {an} vs {fd}"
            );
            assert!((apply_focal(0.0, &v) - v.normalize()).norm() < 1e-15);
            let narrow = apply_focal(0.1, &v);
            assert!(narrow.z > v.normalize().z || v.x.hypot(v.y) < 1e-12);
        }
    }

    /// The zero correction leaves every ray as it was, and a correction keeps the direction's
    /// length and the camera's centre (a ray from the centre still starts there when t = 0).
    #[test]
    fn zero_is_the_identity_and_rotation_keeps_the_centre() {
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        let c = exp_so3(&rand_vec(&mut rng, 3.0));
        let (o, d) = (rand_vec(&mut rng, 2.0), rand_vec(&mut rng, 1.0));
        let (o2, d2) = PoseCorrection::default().apply(&c, &o, &d);
        assert!((o2 - o).norm() < 1e-15 && (d2 - d).norm() < 1e-15);
        let p = PoseCorrection {
            omega: Vector3::new(0.01, -0.02, 0.005),
            t: Vector3::zeros(),
        };
        let (o3, d3) = p.apply(&c, &o, &d);
        assert_eq!(o3, o);
        assert!((d3.norm() - d.norm()).abs() < 1e-12);
        assert!((d3 - d).norm() > 1e-3);
    }
}
