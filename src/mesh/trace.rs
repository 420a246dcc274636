//! Ray queries against a triangle soup: closest hit and occlusion on an obvhs compressed wide
//! BVH. The simulator renders with it, the mesh clean-up asks which cameras see a face, and the
//! held-out normal error casts rays into the true mesh.

use glam::Vec3A;
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// Triangles with a closest-hit and an occlusion query, on an obvhs compressed wide BVH.
/// Coordinates are whatever frame the triangles are given in (f32).
pub struct Tracer {
    bvh: CwBvh,
    /// Triangles in the BVH's primitive order.
    tris: Vec<Triangle>,
    /// BVH order → index in the triangle list the tracer was built from.
    original: Vec<u32>,
}

impl Tracer {
    /// Builds the BVH (sequential PLOC build, so the same input gives the same tree).
    pub fn new(tris: &[Triangle]) -> Self {
        let bvh = build_cwbvh_from_tris(
            tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let original = bvh.primitive_indices.clone();
        let tris = original.iter().map(|&i| tris[i as usize]).collect();
        Self {
            bvh,
            tris,
            original,
        }
    }

    /// The closest hit along `origin + t·dir`, `t ∈ [0, ∞)`: `(triangle index, t)`.
    pub fn closest(&self, origin: Vec3A, dir: Vec3A) -> Option<(u32, f32)> {
        let ray = Ray::new(origin, dir, 0.0, f32::INFINITY);
        let mut hit = RayHit::none();
        if self
            .bvh
            .ray_traverse(ray, &mut hit, |r, id| self.tris[id].intersect(r))
        {
            Some((self.original[hit.primitive_id as usize], hit.t))
        } else {
            None
        }
    }

    /// True when some triangle is hit at `t ∈ [tmin, tmax]`.
    pub fn occluded(&self, origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32) -> bool {
        let ray = Ray::new(origin, dir, tmin, tmax);
        !self
            .bvh
            .ray_traverse_miss(ray, |r, id| self.tris[id].intersect(r))
    }
}
