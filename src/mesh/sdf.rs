//! Analytic signed distance fields (negative inside, normalised space) for tests, benchmarks and
//! the `neus-aug mcubes` cross-check command. Exact distances (Inigo Quilez's formulas for the
//! torus and the box), evaluated in f32.

use std::fmt;
use std::str::FromStr;

/// An analytic shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Sphere: `|p − center| − radius`.
    Sphere { center: [f32; 3], radius: f32 },
    /// Torus around the z axis through `center`: ring radius `major`, tube radius `minor`.
    Torus {
        center: [f32; 3],
        major: f32,
        minor: f32,
    },
    /// Axis-aligned box with half extents `half`.
    Box { center: [f32; 3], half: [f32; 3] },
    /// Union (minimum) of two spheres; two components when they do not overlap.
    TwoSpheres {
        a: [f32; 3],
        ra: f32,
        b: [f32; 3],
        rb: f32,
    },
}

fn len(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn sub(p: [f32; 3], c: [f32; 3]) -> [f32; 3] {
    [p[0] - c[0], p[1] - c[1], p[2] - c[2]]
}

impl Shape {
    /// Signed distance at `p`.
    #[inline]
    pub fn eval(&self, p: [f32; 3]) -> f32 {
        match *self {
            Shape::Sphere { center, radius } => len(sub(p, center)) - radius,
            Shape::Torus {
                center,
                major,
                minor,
            } => {
                let q = sub(p, center);
                let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - major;
                (ring * ring + q[2] * q[2]).sqrt() - minor
            }
            Shape::Box { center, half } => {
                let q = sub(p, center);
                let d: [f32; 3] = std::array::from_fn(|a| q[a].abs() - half[a]);
                let outside = len(d.map(|x| x.max(0.0)));
                outside + d[0].max(d[1]).max(d[2]).min(0.0)
            }
            Shape::TwoSpheres { a, ra, b, rb } => (len(sub(p, a)) - ra).min(len(sub(p, b)) - rb),
        }
    }

    /// Signed distances of a batch of points (the closure form marching cubes takes).
    pub fn eval_batch(&self, pts: &[[f32; 3]]) -> Vec<f32> {
        pts.iter().map(|&p| self.eval(p)).collect()
    }

    /// Euler characteristic `V − E + F` of the closed surface (2 per sphere-like component).
    pub fn euler_characteristic(&self) -> i64 {
        match self {
            Shape::Sphere { .. } | Shape::Box { .. } => 2,
            Shape::Torus { .. } => 0,
            Shape::TwoSpheres { .. } => 4,
        }
    }

    /// The named shapes of the cross-check command, all inside `[-1, 1]^3` with off-grid centres:
    /// `sphere`, `torus`, `box`, `two-spheres`.
    pub fn named(name: &str) -> Option<Shape> {
        Some(match name {
            "sphere" => Shape::Sphere {
                center: [0.031, -0.047, 0.013],
                radius: 0.61,
            },
            "torus" => Shape::Torus {
                center: [0.017, 0.023, -0.011],
                major: 0.52,
                minor: 0.21,
            },
            "box" => Shape::Box {
                center: [0.013, -0.021, 0.037],
                half: [0.43, 0.31, 0.52],
            },
            "two-spheres" => Shape::TwoSpheres {
                a: [-0.41, 0.02, 0.03],
                ra: 0.33,
                b: [0.43, -0.05, 0.01],
                rb: 0.29,
            },
            _ => return None,
        })
    }

    /// Names accepted by [`Shape::named`].
    pub const NAMES: [&'static str; 4] = ["sphere", "torus", "box", "two-spheres"];

    /// Marching cubes of this shape over `[-1, 1]³` with `res` points per axis (tests).
    #[cfg(test)]
    pub(crate) fn mesh_in_unit_cube(&self, res: usize) -> super::TriMesh {
        let grid = super::GridSpec::cube([-1.0; 3], [1.0; 3], res);
        super::marching_cubes(
            &|p: &[[f32; 3]]| self.eval_batch(p),
            &grid,
            &super::McOptions::default(),
        )
        .unwrap()
    }
}

/// Error of parsing a shape name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown SDF shape {0:?} (expected one of: sphere, torus, box, two-spheres)")]
pub struct UnknownShape(pub String);

impl FromStr for Shape {
    type Err = UnknownShape;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Shape::named(s).ok_or_else(|| UnknownShape(s.to_string()))
    }
}

impl fmt::Display for Shape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self:?}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_at_known_points() {
        let s = Shape::Sphere {
            center: [1.0, 0.0, 0.0],
            radius: 0.5,
        };
        assert_eq!(s.eval([1.0, 0.0, 0.0]), -0.5);
        assert_eq!(s.eval([2.0, 0.0, 0.0]), 0.5);
        let t = Shape::Torus {
            center: [0.0; 3],
            major: 0.5,
            minor: 0.2,
        };
        assert!((t.eval([0.5, 0.0, 0.0]) + 0.2).abs() < 1e-7);
        assert!((t.eval([0.0, 0.0, 0.0]) - 0.3).abs() < 1e-7);
        assert!((t.eval([0.0, 0.5, 0.5]) - 0.3).abs() < 1e-7);
        let b = Shape::Box {
            center: [0.0; 3],
            half: [1.0, 2.0, 3.0],
        };
        assert_eq!(b.eval([0.0, 0.0, 0.0]), -1.0);
        assert_eq!(b.eval([2.0, 0.0, 0.0]), 1.0);
        assert!((b.eval([2.0, 3.0, 0.0]) - 2f32.sqrt()).abs() < 1e-6);
        for name in Shape::NAMES {
            assert!(name.parse::<Shape>().is_ok());
        }
        assert!("cube".parse::<Shape>().is_err());
    }
}
