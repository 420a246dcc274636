//! Triangle meshes from signed distance fields: marching cubes, the two-pass extraction of
//! instant-nsr-pl, and topology checks.
//!
//! Frame and units: the SDF is sampled in the **normalised space** of the scene (the object inside
//! the unit sphere, Totoro97/NeuS `models/dataset.py`); [`extract::to_world`] maps a mesh to world
//! millimetres with the scene's `scale_mat` before it is written or scored.
//!
//! Conventions (one place for each):
//! - the SDF is negative inside; a grid value `v` is **inside iff `v <= iso`** ([`inside`]). Values
//!   exactly equal to the iso level therefore count as inside, as in PyMCubes, scikit-image and
//!   `isosurface` 0.1.0-alpha.0 (each treats `v > level` as the other side);
//! - triangles are counter-clockwise seen from outside (outward normals), the convention of
//!   `dtu_eval::mesh::TriMesh`;
//! - grid point `(i, j, k)` sits at `min + (max − min)·(i, j, k)/(res − 1)` (per axis), the
//!   `linspace` grid of instant-nsr-pl's `MarchingCubeHelper` (`models/geometry.py`);
//! - one vertex per grid edge whose end values lie on different sides, at the linear interpolation
//!   of the two values, shared by every cell around that edge (watertight);
//! - `NaN` anywhere in the grid is an error ([`McError::NanSdf`]); `±∞` are allowed and classified
//!   by sign (a crossing next to an infinite value sits on the finite end).
//!
//! Entry points: [`marching_cubes`] (SDF closure, evaluated slab by slab in parallel batches),
//! [`marching_cubes_values`] (a grid already in memory), [`extract::extract_two_pass`] (coarse box,
//! then the padded bounds of the coarse mesh), [`topology::TopologyReport`] (boundary and
//! non-manifold edges, Euler characteristic), [`reference::marching_cubes_reference`] (the slow,
//! obviously correct path the fast one is tested against), [`closing`] (the optional grey-scale
//! closing of the grid values before extraction, `McOptions::close_radius`) and [`sdf`]
//! (analytic test shapes).
//!
//! ```
//! use neus_aug::mesh::{marching_cubes, sdf::Shape, GridSpec, McOptions, TopologyReport};
//!
//! let torus = Shape::named("torus").unwrap();
//! let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 48);
//! let mesh = marching_cubes(&|p: &[[f32; 3]]| torus.eval_batch(p), &grid, &McOptions::default())?;
//! let topo = TopologyReport::of(&mesh);
//! assert!(topo.is_closed_manifold());
//! assert_eq!(topo.euler_characteristic, 0);
//! # Ok::<(), neus_aug::mesh::McError>(())
//! ```

pub mod clean;
pub mod closing;
pub mod extract;
mod mcubes;
pub mod reference;
pub mod sdf;
pub mod subdivide;
pub mod tables;
pub mod topology;
pub mod trace;

pub use dtu_eval::mesh::TriMesh;
pub use extract::{extract_two_pass, to_world, TwoPassOptions};
pub use mcubes::{marching_cubes, marching_cubes_values, sample_grid};
pub use topology::TopologyReport;

/// Whether a grid value counts as inside the surface (`v <= iso`); `NaN` is rejected earlier.
#[inline(always)]
pub fn inside(v: f32, iso: f32) -> bool {
    v <= iso
}

/// A regular grid of sample points over an axis-aligned box, in normalised space.
///
/// `res[a]` points along axis `a` (at least 2), so `res[a] − 1` cells; point `(i, j, k)` is at
/// `min + (max − min)·(i, j, k)/(res − 1)`. Grid values are stored `[k][j][i]` (x fastest).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Lower corner of the box.
    pub min: [f32; 3],
    /// Upper corner of the box.
    pub max: [f32; 3],
    /// Points per axis (x, y, z).
    pub res: [usize; 3],
}

impl GridSpec {
    /// A grid with `res` points on every axis.
    pub fn cube(min: [f32; 3], max: [f32; 3], res: usize) -> Self {
        Self {
            min,
            max,
            res: [res; 3],
        }
    }

    /// Checks the resolution (at least 2 points per axis, at most `u32::MAX` per axis, fewer than
    /// `2^40` in all) and the box (finite, `min < max` on every axis).
    pub fn validate(&self) -> Result<(), McError> {
        if self.res.iter().any(|&r| r < 2) {
            return Err(McError::Resolution { res: self.res });
        }
        let n = self
            .res
            .iter()
            .try_fold(1u64, |acc, &r| acc.checked_mul(r as u64));
        if self.res.iter().any(|&r| r as u64 > u32::MAX as u64) || n.is_none_or(|n| n >= 1 << 40) {
            return Err(McError::TooLarge { res: self.res });
        }
        let ok = (0..3).all(|a| {
            self.min[a].is_finite() && self.max[a].is_finite() && self.min[a] < self.max[a]
        });
        if !ok {
            return Err(McError::Box {
                min: self.min,
                max: self.max,
            });
        }
        Ok(())
    }

    /// Number of grid points.
    pub fn n_points(&self) -> usize {
        self.res.iter().product()
    }

    /// Cell size along each axis.
    pub fn cell_size(&self) -> [f32; 3] {
        std::array::from_fn(|a| (self.max[a] - self.min[a]) / (self.res[a] - 1) as f32)
    }

    /// Coordinates of the grid points along `axis` (`res[axis]` values, first `min`, last `max`),
    /// computed in f64 and rounded once.
    pub fn coords(&self, axis: usize) -> Vec<f64> {
        let n = self.res[axis];
        let (lo, hi) = (self.min[axis] as f64, self.max[axis] as f64);
        (0..n)
            .map(|i| {
                if i + 1 == n {
                    hi
                } else {
                    lo + (hi - lo) * (i as f64 / (n - 1) as f64)
                }
            })
            .map(|x| x as f32 as f64)
            .collect()
    }
}

/// Options of the streaming extraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McOptions {
    /// Iso level (0 for an SDF).
    pub iso: f32,
    /// Points per call of the SDF closure (default 65 536); batches run in parallel (rayon).
    pub batch_points: usize,
    /// Grid values held in memory at once (default 2^22, 16 MiB of f32): the grid is evaluated in
    /// slabs of whole z-planes of about this many points (at least one plane), plus the plane
    /// carried over from the previous slab.
    pub slab_points: usize,
    /// Half-width, in grid points, of the cube of the grey-scale closing applied to the values
    /// before extraction ([`closing`]): it fills tunnels and pinholes narrower than about
    /// `2·close_radius` cells. 0 (the default) extracts the raw level set.
    pub close_radius: usize,
}

impl Default for McOptions {
    fn default() -> Self {
        Self {
            iso: 0.0,
            batch_points: 1 << 16,
            slab_points: 1 << 22,
            close_radius: 0,
        }
    }
}

/// Why marching cubes could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum McError {
    /// Fewer than two points on some axis.
    #[error("marching cubes needs at least 2 grid points per axis, got resolution {res:?}")]
    Resolution { res: [usize; 3] },
    /// The grid has too many points.
    #[error("grid resolution {res:?} is too large (at most 2^32 - 1 per axis and 2^40 points)")]
    TooLarge { res: [usize; 3] },
    /// The box is empty, inverted or not finite.
    #[error("grid box must be finite with min < max on every axis, got min {min:?}, max {max:?}")]
    Box { min: [f32; 3], max: [f32; 3] },
    /// The iso level is not finite.
    #[error("iso level must be finite, got {iso}")]
    Iso { iso: f32 },
    /// The SDF closure answered a batch with the wrong number of values.
    #[error("the SDF returned {got} values for a batch of {expected} points")]
    SdfLength { expected: usize, got: usize },
    /// A grid value is NaN.
    #[error("SDF is NaN at grid point {index:?} (position {position:?}, normalised space)")]
    NanSdf {
        index: [usize; 3],
        position: [f32; 3],
    },
    /// A value array does not match its grid.
    #[error("value array has {got} entries, grid {res:?} needs {expected}")]
    ValuesLength {
        got: usize,
        expected: usize,
        res: [usize; 3],
    },
    /// More vertices than 32-bit face indices can address.
    #[error("the mesh would have more than 2^32 - 1 vertices")]
    TooManyVertices,
}
