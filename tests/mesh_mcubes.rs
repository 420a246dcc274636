//! Marching cubes against the `isosurface` 0.1.0-alpha.0 oracle (same vertex and triangle counts,
//! same vertex positions as sets) and against the slow reference (same bytes), plus the
//! degenerate inputs: empty results, NaN, bad resolutions and boxes, exact iso values, infinities.

use isosurface::distance::Signed;
use isosurface::extractor::IndexedVertices;
use isosurface::math::Vec3;
use isosurface::sampler::Sampler;
use isosurface::source::ScalarSource;
use isosurface::MarchingCubes;
use neus_aug::mesh::closing::close_values;
use neus_aug::mesh::reference::marching_cubes_reference;
use neus_aug::mesh::sdf::Shape;
use neus_aug::mesh::{
    marching_cubes, marching_cubes_values, sample_grid, GridSpec, McError, McOptions, TriMesh,
};
use rand::{Rng, SeedableRng};
use std::collections::HashMap;

/// Grid values in memory, served to the oracle by grid index so both sides see the same numbers.
struct GridSource {
    values: Vec<f32>,
    res: [usize; 3],
    /// The oracle samples `(x, y, z)·(size − 1)` at integer points; this maps back to indices.
    scale: f32,
}

impl ScalarSource for GridSource {
    fn sample_scalar(&self, p: Vec3) -> Signed {
        let idx = [p.x, p.y, p.z].map(|c| (c * self.scale).round() as usize);
        let [nx, ny, _] = self.res;
        Signed(self.values[(idx[2] * ny + idx[1]) * nx + idx[0]])
    }
}

/// The oracle's grid for `size`: `size` points on [0, 1] in x and y, `size + 1` points on
/// [0, size/(size − 1)] in z (its `PrimalGrid` samples one plane past 1 along z).
fn oracle_grid(size: usize) -> GridSpec {
    GridSpec {
        min: [0.0; 3],
        max: [1.0, 1.0, size as f32 / (size - 1) as f32],
        res: [size, size, size + 1],
    }
}

fn oracle(values: &[f32], size: usize) -> TriMesh {
    let src = GridSource {
        values: values.to_vec(),
        res: [size, size, size + 1],
        scale: (size - 1) as f32,
    };
    let (mut v, mut idx) = (Vec::new(), Vec::new());
    MarchingCubes::<Signed>::new(size).extract(
        &Sampler::new(&src),
        &mut IndexedVertices::new(&mut v, &mut idx),
    );
    TriMesh {
        vertices: v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
        faces: idx.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

/// Largest distance from a point of one set to the nearest point of the other (both directions).
fn set_distance(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    fn one_way(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
        const Q: f32 = 1e-3;
        let key = |p: &[f32; 3]| p.map(|c| (c / Q).floor() as i64);
        let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
        for (n, p) in b.iter().enumerate() {
            grid.entry(key(p)).or_default().push(n);
        }
        a.iter()
            .map(|p| {
                let k = key(p);
                let mut best = f32::INFINITY;
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            for &n in grid
                                .get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                                .into_iter()
                                .flatten()
                            {
                                let q = b[n];
                                let d = ((p[0] - q[0]).powi(2)
                                    + (p[1] - q[1]).powi(2)
                                    + (p[2] - q[2]).powi(2))
                                .sqrt();
                                best = best.min(d);
                            }
                        }
                    }
                }
                best
            })
            .fold(0.0, f32::max)
    }
    one_way(a, b).max(one_way(b, a))
}

/// The mesh as raw bits (f32 `==` would call −0.0 and +0.0 equal).
fn bits(m: &TriMesh) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
    (
        m.vertices.iter().map(|v| v.map(f32::to_bits)).collect(),
        m.faces.clone(),
    )
}

fn assert_matches_oracle(values: &[f32], size: usize, what: &str) -> TriMesh {
    let grid = oracle_grid(size);
    let ours = marching_cubes_values(values, &grid, 0.0).unwrap();
    let theirs = oracle(values, size);
    assert_eq!(
        (ours.vertices.len(), ours.faces.len()),
        (theirs.vertices.len(), theirs.faces.len()),
        "{what}: (vertices, faces) differ from isosurface 0.1.0-alpha.0"
    );
    let d = set_distance(&ours.vertices, &theirs.vertices);
    assert!(d < 2e-6, "{what}: vertex sets differ by up to {d}");
    ours
}

/// Values of `shape` (defined on [-1, 1]^3) on the oracle grid mapped to [0, 1]^3.
fn shape_values(shape: Shape, size: usize) -> Vec<f32> {
    let sdf = move |pts: &[[f32; 3]]| -> Vec<f32> {
        pts.iter()
            .map(|p| shape.eval(p.map(|c| 2.0 * c - 1.0)))
            .collect()
    };
    sample_grid(&sdf, &oracle_grid(size), &McOptions::default()).unwrap()
}

#[test]
fn every_case_matches_the_oracle() {
    // A 2×2×3 grid: the case under test in the lower cell, the top plane outside. Values have
    // random magnitudes so vertices are not all at edge midpoints.
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
    for case in 0..256usize {
        let mut values = vec![1.0f32; 12];
        for c in 0..8 {
            let mag = rng.random_range(0.05f32..1.0);
            let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            values[(dz * 2 + dy) * 2 + dx] = if (case >> c) & 1 == 1 { -mag } else { mag };
        }
        for v in &mut values[8..] {
            *v = rng.random_range(0.05f32..1.0);
        }
        assert_matches_oracle(&values, 2, &format!("case {case:#010b}"));
    }
}

#[test]
fn analytic_shapes_match_the_oracle() {
    for (name, size) in [
        ("sphere", 40),
        ("torus", 37),
        ("box", 33),
        ("two-spheres", 41),
    ] {
        let shape = Shape::named(name).unwrap();
        let values = shape_values(shape, size);
        let mesh = assert_matches_oracle(&values, size, name);
        assert!(!mesh.faces.is_empty(), "{name}");
    }
}

#[test]
fn random_offset_spheres_match_the_oracle_and_the_reference() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(2024);
    for trial in 0..12 {
        let size = rng.random_range(9..30);
        let shape = Shape::Sphere {
            center: std::array::from_fn(|_| rng.random_range(-0.3f32..0.3)),
            // Some spheres are cut by the box: open meshes must match as well.
            radius: rng.random_range(0.2f32..1.1),
        };
        let values = shape_values(shape, size);
        let ours = assert_matches_oracle(&values, size, &format!("trial {trial}: {shape}"));
        let slow = marching_cubes_reference(&values, &oracle_grid(size), 0.0).unwrap();
        assert_eq!(ours, slow, "trial {trial}");
    }
}

/// Streaming the SDF in slabs of 1, 2 or 5 planes and odd batch sizes gives exactly the bytes
/// of the reference on the whole grid, with the surface crossing every slab boundary; with the
/// closing (`close_radius` 1–3, windows longer than a slab and than the grid's 2 planes), the
/// bytes of the reference on the whole grid closed in memory.
#[test]
fn slabs_and_batches_give_the_reference_bytes() {
    let grids = [
        GridSpec::cube([-1.0; 3], [1.0; 3], 33),
        GridSpec {
            min: [-0.9, -1.0, -0.8],
            max: [1.0, 0.7, 0.95],
            res: [37, 29, 41],
        },
        // More than 64 points along x: bit words and their boundaries.
        GridSpec {
            min: [-1.0; 3],
            max: [1.0; 3],
            res: [130, 7, 9],
        },
        GridSpec {
            min: [-1.0; 3],
            max: [1.0; 3],
            res: [65, 66, 2],
        },
    ];
    for name in Shape::NAMES {
        let shape = Shape::named(name).unwrap();
        let sdf = move |pts: &[[f32; 3]]| shape.eval_batch(pts);
        for grid in &grids {
            let values = sample_grid(&sdf, grid, &McOptions::default()).unwrap();
            let plane = grid.res[0] * grid.res[1];
            // The streamed closing (`close_radius`) against the whole grid closed in memory.
            for close_radius in 0..=3 {
                let mut closed = values.clone();
                close_values(&mut closed, grid.res, close_radius);
                let slow = marching_cubes_reference(&closed, grid, 0.0).unwrap();
                for (slab_planes, batch) in [(1, 7), (2, 1000), (5, 64), (1000, 1 << 16)] {
                    let opts = McOptions {
                        iso: 0.0,
                        batch_points: batch,
                        slab_points: slab_planes * plane,
                        close_radius,
                    };
                    let fast = marching_cubes(&sdf, grid, &opts).unwrap();
                    assert_eq!(
                        fast, slow,
                        "{name} on {grid:?}, slabs of {slab_planes} planes, closing {close_radius}"
                    );
                }
                assert_eq!(marching_cubes_values(&closed, grid, 0.0).unwrap(), slow);
            }
        }
    }
}

/// Tilted planes through the points where 64-bit words meet (x index 63/64, 127/128): every
/// combination of a uniform column on one side of the boundary and a mixed one on the other.
#[test]
fn surfaces_across_bit_word_boundaries_give_the_reference_bytes() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(64);
    let grid = GridSpec {
        min: [-1.0; 3],
        max: [1.0; 3],
        res: [200, 6, 5],
    };
    let xs = grid.coords(0);
    for trial in 0..200 {
        let b = [63usize, 64, 127, 128][trial % 4];
        let x0 = (xs[b] + rng.random_range(-1.0..1.0) * (xs[1] - xs[0])) as f32;
        let n = [
            if trial % 8 < 4 { 1.0f32 } else { -1.0 },
            rng.random_range(-0.05f32..0.05),
            rng.random_range(-0.05f32..0.05),
        ];
        let y0 = rng.random_range(-1.0f32..1.0);
        let sdf = move |pts: &[[f32; 3]]| -> Vec<f32> {
            pts.iter()
                .map(|p| n[0] * (p[0] - x0) + n[1] * (p[1] - y0) + n[2] * p[2])
                .collect()
        };
        let values = sample_grid(&sdf, &grid, &McOptions::default()).unwrap();
        let slow = marching_cubes_reference(&values, &grid, 0.0).unwrap();
        assert!(!slow.faces.is_empty());
        let fast = marching_cubes_values(&values, &grid, 0.0).unwrap();
        assert_eq!(
            fast, slow,
            "trial {trial}: plane through x = {x0}, normal {n:?}"
        );
    }
}

#[test]
fn iso_levels_other_than_zero() {
    let shape = Shape::named("torus").unwrap();
    let sdf = move |pts: &[[f32; 3]]| shape.eval_batch(pts);
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 31);
    let values = sample_grid(&sdf, &grid, &McOptions::default()).unwrap();
    for iso in [-0.1f32, 0.05, 0.2] {
        let opts = McOptions {
            iso,
            ..McOptions::default()
        };
        let fast = marching_cubes(&sdf, &grid, &opts).unwrap();
        assert_eq!(fast, marching_cubes_reference(&values, &grid, iso).unwrap());
        // The iso-0.2 torus tube of radius 0.41 still has a hole (0.52 > 0.41).
        for v in &fast.vertices {
            let d = shape.eval(*v) - iso;
            assert!(
                d.abs() < 0.02,
                "vertex {v:?} is {d} off the iso surface {iso}"
            );
        }
    }
}

/// Same bytes in a pool of 1, 2 and 3 threads.
#[test]
fn output_does_not_depend_on_the_thread_count() {
    let shape = Shape::named("two-spheres").unwrap();
    let sdf = move |pts: &[[f32; 3]]| shape.eval_batch(pts);
    let grid = GridSpec {
        min: [-1.0; 3],
        max: [1.0; 3],
        res: [97, 83, 71],
    };
    let opts = McOptions {
        iso: 0.0,
        batch_points: 3000,
        slab_points: 5 * 97 * 83,
        close_radius: 0,
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| marching_cubes(&sdf, &grid, &opts).unwrap())
    };
    let one = bits(&run(1));
    assert!(one.1.len() > 10_000);
    assert_eq!(one, bits(&run(2)));
    assert_eq!(one, bits(&run(3)));
}

#[test]
fn vertices_lie_within_a_fraction_of_a_cell_of_the_surface() {
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 65);
    let h = grid.cell_size()[0];
    for name in Shape::NAMES {
        let shape = Shape::named(name).unwrap();
        let mesh = marching_cubes(
            &|p: &[[f32; 3]]| shape.eval_batch(p),
            &grid,
            &Default::default(),
        )
        .unwrap();
        let worst = mesh
            .vertices
            .iter()
            .map(|v| shape.eval(*v).abs())
            .fold(0.0f32, f32::max);
        // Linear interpolation of an exact SDF along an edge: the box's corners are the worst
        // case (distance not linear across them), still well inside half a cell.
        assert!(
            worst < 0.5 * h,
            "{name}: a vertex is {worst} from the surface, cell {h}"
        );
        if name == "sphere" {
            assert!(worst < 0.02 * h, "sphere: {worst} vs cell {h}");
        }
    }
}

#[test]
fn values_equal_to_the_iso_level_count_as_inside() {
    // 3×3×3 grid, centre exactly 0, everything else +1: the centre is inside, so it is cut off
    // (6 vertices, all at the centre, 8 degenerate triangles), as PyMCubes and scikit-image do.
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 3);
    let mut values = vec![1.0f32; 27];
    values[13] = 0.0;
    let m = marching_cubes_values(&values, &grid, 0.0).unwrap();
    assert_eq!((m.vertices.len(), m.faces.len()), (6, 8));
    assert!(m.vertices.iter().all(|v| *v == [0.0, 0.0, 0.0]));
    assert_eq!(m, marching_cubes_reference(&values, &grid, 0.0).unwrap());
    // Everything else −1: all inside, nothing to extract.
    let values: Vec<f32> = (0..27).map(|n| if n == 13 { 0.0 } else { -1.0 }).collect();
    assert_eq!(
        marching_cubes_values(&values, &grid, 0.0).unwrap(),
        TriMesh::default()
    );
    // A sphere through grid points (radius 0.5 on a grid of step 0.25): exact zeros on the
    // surface; counts still agree with the oracle.
    let size = 9;
    let values: Vec<f32> = shape_values(
        Shape::Sphere {
            center: [0.0; 3],
            radius: 0.5,
        },
        size,
    );
    assert!(values.contains(&0.0));
    assert_matches_oracle(&values, size, "sphere through grid points");
}

#[test]
fn no_sign_change_gives_an_empty_mesh() {
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 17);
    for c in [1.0f32, -1.0, 0.0] {
        let m = marching_cubes(
            &|p: &[[f32; 3]]| vec![c; p.len()],
            &grid,
            &Default::default(),
        )
        .unwrap();
        assert_eq!(m, TriMesh::default(), "constant {c}");
    }
}

#[test]
fn infinite_values_are_classified_by_sign_and_give_finite_vertices() {
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 12);
    let shape = Shape::named("sphere").unwrap();
    let sdf = move |pts: &[[f32; 3]]| -> Vec<f32> {
        pts.iter()
            .map(|&p| {
                let d = shape.eval(p);
                if d > 0.3 {
                    f32::INFINITY
                } else if d < -0.3 {
                    f32::NEG_INFINITY
                } else {
                    d
                }
            })
            .collect()
    };
    let values = sample_grid(&sdf, &grid, &Default::default()).unwrap();
    assert!(values.iter().any(|v| v.is_infinite()));
    let m = marching_cubes(&sdf, &grid, &Default::default()).unwrap();
    assert!(!m.faces.is_empty());
    assert!(m.validate().is_ok());
    assert_eq!(m, marching_cubes_reference(&values, &grid, 0.0).unwrap());
    // A grid of only ±∞ across the surface: crossings at midpoints, still finite.
    let sdf = |pts: &[[f32; 3]]| -> Vec<f32> {
        pts.iter()
            .map(|p| {
                if p[0] < 0.1 {
                    f32::NEG_INFINITY
                } else {
                    f32::INFINITY
                }
            })
            .collect()
    };
    let m = marching_cubes(&sdf, &grid, &Default::default()).unwrap();
    assert!(!m.faces.is_empty() && m.validate().is_ok());
}

#[test]
fn nan_is_an_error_naming_the_first_grid_point() {
    let grid = GridSpec {
        min: [-1.0; 3],
        max: [1.0; 3],
        res: [9, 8, 7],
    };
    let sdf = |pts: &[[f32; 3]]| -> Vec<f32> {
        pts.iter()
            .map(|p| {
                if p[2] > 0.3 && p[0] > 0.5 && p[1] < -0.5 {
                    f32::NAN
                } else {
                    p[0]
                }
            })
            .collect()
    };
    // The closing's minimum and maximum would drop a NaN: it is reported before them.
    for close_radius in 1..=2 {
        let opts = McOptions {
            close_radius,
            ..McOptions::default()
        };
        let err = marching_cubes(&sdf, &grid, &opts).unwrap_err();
        assert!(
            matches!(
                err,
                McError::NanSdf {
                    index: [7, 0, 4],
                    ..
                }
            ),
            "{err}"
        );
    }
    let err = marching_cubes(&sdf, &grid, &Default::default()).unwrap_err();
    // First NaN in [k][j][i] order: k = 4 (z = 1/3), j = 0 (y = −1), i = 7 (x = 0.75).
    let McError::NanSdf { index, position } = err.clone() else {
        panic!("{err}")
    };
    assert_eq!(index, [7, 0, 4]);
    assert_eq!(position, [0.75, -1.0, (-1.0f64 + 2.0 * (4.0 / 6.0)) as f32]);
    assert!(err.to_string().contains("NaN") && err.to_string().contains("[7, 0, 4]"));
    let values = sample_grid(&sdf, &grid, &Default::default()).unwrap();
    assert_eq!(
        marching_cubes_reference(&values, &grid, 0.0).unwrap_err(),
        err
    );
    assert_eq!(marching_cubes_values(&values, &grid, 0.0).unwrap_err(), err);
}

#[test]
fn bad_grids_and_closures_are_clear_errors() {
    let sdf = |p: &[[f32; 3]]| vec![0.5; p.len()];
    let opts = McOptions::default();
    for res in [[1, 5, 5], [5, 0, 5], [5, 5, 1]] {
        let g = GridSpec {
            min: [-1.0; 3],
            max: [1.0; 3],
            res,
        };
        assert_eq!(
            marching_cubes(&sdf, &g, &opts).unwrap_err(),
            McError::Resolution { res }
        );
    }
    let g = GridSpec {
        min: [0.0, 0.0, 1.0],
        max: [1.0, 1.0, 1.0],
        res: [4; 3],
    };
    assert!(matches!(
        marching_cubes(&sdf, &g, &opts),
        Err(McError::Box { .. })
    ));
    let g = GridSpec {
        min: [0.0, f32::NAN, 0.0],
        max: [1.0; 3],
        res: [4; 3],
    };
    assert!(matches!(
        marching_cubes(&sdf, &g, &opts),
        Err(McError::Box { .. })
    ));
    let g = GridSpec::cube([-1.0; 3], [1.0; 3], 5);
    let short = |p: &[[f32; 3]]| vec![0.5; p.len() - 1];
    assert!(matches!(
        marching_cubes(&short, &g, &opts),
        Err(McError::SdfLength { .. })
    ));
    let nan_iso = McOptions {
        iso: f32::NAN,
        ..opts
    };
    assert!(matches!(
        marching_cubes(&sdf, &g, &nan_iso),
        Err(McError::Iso { .. })
    ));
    assert!(matches!(
        marching_cubes_values(&[0.0; 10], &g, 0.0),
        Err(McError::ValuesLength { .. })
    ));
}
