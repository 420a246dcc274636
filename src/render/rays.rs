//! Ray–box intersection and the stratified ray marcher.
//!
//! Rays live in the normalised space (object inside the unit sphere): origins `[n][3]` and unit
//! directions `[n][3]`, f32. The marched region is the axis-aligned box `[-r, r]³` around the unit
//! sphere (instant-nsr-pl `scene_aabb`, `radius: 1.0`). Marching follows nerfacc 0.3
//! `ray_marching` as instant-nsr-pl calls it: fixed step `Δ = 1.732·2r / num_samples_per_ray`,
//! start at the box entry `t_min` plus a per-ray jitter `u·Δ` (u ~ U[0,1) when stratified, 0
//! otherwise), intervals `[t, t + Δ]` whose midpoint is inside the box, kept only when the
//! occupancy grid marks the midpoint's cell occupied.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::occupancy::OccupancyGrid;

/// Entry and exit distances of a ray through `[-r, r]³`, with the entry clamped to `t ≥ 0`
/// (origins inside the box start at 0). `None` when the ray misses, only touches an edge, or the
/// box lies behind the origin.
pub fn ray_aabb(o: [f32; 3], d: [f32; 3], r: f32) -> Option<(f32, f32)> {
    let mut t0 = f32::NEG_INFINITY;
    let mut t1 = f32::INFINITY;
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k].abs() > r {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[k];
        let a = (-r - o[k]) * inv;
        let b = (r - o[k]) * inv;
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    let t0 = t0.max(0.0);
    if t1 <= t0 || !t0.is_finite() || !t1.is_finite() {
        return None;
    }
    Some((t0, t1))
}

/// Samples of a batch of rays, packed ray after ray.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RaySamples {
    /// `[n_rays + 1]`: samples of ray `i` are `ray_start[i]..ray_start[i+1]`.
    pub ray_start: Vec<usize>,
    /// Interval midpoints `t` along the ray `[n_samples]` (normalised units).
    pub t: Vec<f32>,
    /// Interval lengths `[n_samples]`.
    pub dt: Vec<f32>,
}

impl RaySamples {
    pub fn n_samples(&self) -> usize {
        self.t.len()
    }
    pub fn n_rays(&self) -> usize {
        self.ray_start.len().saturating_sub(1)
    }
    pub fn range(&self, ray: usize) -> std::ops::Range<usize> {
        self.ray_start[ray]..self.ray_start[ray + 1]
    }
}

/// Marches every ray. `jitter[i] ∈ [0,1)` offsets ray `i`'s first interval (empty slice: no
/// jitter). `grid = None` keeps every interval.
pub fn march_rays(
    origins: &[[f32; 3]],
    dirs: &[[f32; 3]],
    radius: f32,
    step: f32,
    jitter: &[f32],
    grid: Option<&OccupancyGrid>,
) -> RaySamples {
    let mut s = RaySamples {
        ray_start: Vec::with_capacity(origins.len() + 1),
        ..Default::default()
    };
    s.ray_start.push(0);
    for (i, (o, d)) in origins.iter().zip(dirs).enumerate() {
        if let Some((tmin, tmax)) = ray_aabb(*o, *d, radius) {
            let u = jitter.get(i).copied().unwrap_or(0.0);
            let mut k = 0u32;
            let t_start = tmin + u * step;
            loop {
                // Index-based positions: no drift from repeated addition.
                let t0 = t_start + k as f32 * step;
                let mid = t0 + 0.5 * step;
                if mid >= tmax || mid.is_nan() {
                    break;
                }
                k += 1;
                let p = [o[0] + d[0] * mid, o[1] + d[1] * mid, o[2] + d[2] * mid];
                if grid.is_none_or(|g| g.is_occupied(p)) {
                    s.t.push(mid);
                    s.dt.push(step);
                }
            }
        }
        s.ray_start.push(s.t.len());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_intersection_cases() {
        // Straight through the centre.
        let (a, b) = ray_aabb([0.0, 0.0, -3.0], [0.0, 0.0, 1.0], 1.0).unwrap();
        assert_eq!((a, b), (2.0, 4.0));
        // Misses.
        assert!(ray_aabb([0.0, 2.0, -3.0], [0.0, 0.0, 1.0], 1.0).is_none());
        // Box behind the origin.
        assert!(ray_aabb([0.0, 0.0, 3.0], [0.0, 0.0, 1.0], 1.0).is_none());
        // Origin inside: starts at 0.
        let (a, b) = ray_aabb([0.0, 0.0, 0.5], [0.0, 0.0, 1.0], 1.0).unwrap();
        assert_eq!((a, b), (0.0, 0.5));
        // Touching an edge only: empty.
        let d = std::f32::consts::FRAC_1_SQRT_2;
        assert!(ray_aabb([-2.0, 0.0, 0.0], [d, d, 0.0], 1.0).is_none());
    }

    #[test]
    fn marching_counts_and_jitter() {
        let o = [[0.0, 0.0, -3.0], [0.0, 5.0, -3.0]];
        let d = [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        let s = march_rays(&o, &d, 1.0, 0.1, &[], None);
        assert_eq!(s.range(0).len(), 20);
        assert_eq!(
            s.range(1).len(),
            0,
            "a ray that misses the box has no sample"
        );
        assert!((s.t[0] - 2.05).abs() < 1e-6);
        let sj = march_rays(&o, &d, 1.0, 0.1, &[0.3, 0.3], None);
        assert_eq!(sj.range(0).len(), 20);
        assert!((sj.t[0] - 2.08).abs() < 1e-6);
        assert!(sj.t.iter().all(|&t| t > 2.0 && t < 4.0));
    }
}
