//! Watertightness and topology of extracted meshes (no boundary or non-manifold edges, consistent
//! outward orientation, Euler characteristic), the two-pass extraction and the map to world mm.

use neus_aug::mesh::extract::refined_grid;
use neus_aug::mesh::sdf::Shape;
use neus_aug::mesh::topology::signed_volume;
use neus_aug::mesh::{
    extract_two_pass, marching_cubes, to_world, GridSpec, McOptions, TopologyReport, TriMesh,
    TwoPassOptions,
};
use neus_aug::scene::Normalization;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

fn mesh_of(shape: Shape, grid: &GridSpec) -> TriMesh {
    marching_cubes(
        &|p: &[[f32; 3]]| shape.eval_batch(p),
        grid,
        &McOptions::default(),
    )
    .unwrap()
}

#[test]
fn closed_shapes_give_closed_oriented_manifolds_with_the_right_euler_characteristic() {
    for res in [24, 57, 96] {
        let grid = GridSpec::cube([-1.0; 3], [1.0; 3], res);
        for name in Shape::NAMES {
            let shape = Shape::named(name).unwrap();
            let m = mesh_of(shape, &grid);
            let r = TopologyReport::of(&m);
            assert!(r.is_closed_manifold(), "{name} at {res}: {r:?}");
            assert_eq!(r.unreferenced_vertices, 0, "{name}");
            assert_eq!(
                r.euler_characteristic,
                shape.euler_characteristic(),
                "{name} at {res}: {r:?}"
            );
            let expected_components = if name == "two-spheres" { 2 } else { 1 };
            assert_eq!(r.components, expected_components, "{name}");
            assert!(signed_volume(&m) > 0.0, "{name}: faces point inward");
        }
    }
}

#[test]
fn enclosed_volumes_approach_the_analytic_ones() {
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 80);
    let cases = [
        ("sphere", 4.0 / 3.0 * PI * 0.61f64.powi(3)),
        ("torus", 2.0 * PI * PI * 0.52 * 0.21f64.powi(2)),
        ("box", 8.0 * 0.43 * 0.31 * 0.52),
    ];
    for (name, exact) in cases {
        let v = signed_volume(&mesh_of(Shape::named(name).unwrap(), &grid));
        assert!(
            ((v - exact) / exact).abs() < 0.01,
            "{name}: volume {v}, exact {exact}"
        );
    }
}

/// Random unions of spheres (overlapping or not), random boxes and anisotropic grids: every mesh
/// is closed and edge-manifold, with Euler characteristic 2 per component when the components
/// are spheres (a union of overlapping balls can have handles, so only χ ≤ 2·components there).
#[test]
fn random_blobs_are_watertight() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    for trial in 0..30 {
        let a: [f32; 3] = std::array::from_fn(|_| rng.random_range(-0.4f32..0.4));
        let b: [f32; 3] = std::array::from_fn(|_| rng.random_range(-0.4f32..0.4));
        let shape = Shape::TwoSpheres {
            a,
            ra: rng.random_range(0.05f32..0.5),
            b,
            rb: rng.random_range(0.05f32..0.5),
        };
        let res = [
            rng.random_range(8..48),
            rng.random_range(8..48),
            rng.random_range(8..48),
        ];
        let grid = GridSpec {
            min: [-1.0, -0.95, -1.0],
            max: [0.97, 1.0, 1.0],
            res,
        };
        let m = mesh_of(shape, &grid);
        let r = TopologyReport::of(&m);
        assert!(
            r.is_closed_manifold(),
            "trial {trial}: {shape} on {res:?}: {r:?}"
        );
        assert!(r.euler_characteristic <= 2 * r.components as i64, "{r:?}");
        assert!(m.faces.is_empty() || signed_volume(&m) > 0.0);
    }
}

/// White noise inside a border of outside values: every ambiguous face and cell configuration
/// occurs many times, and the mesh must still be closed, edge-manifold and consistently oriented.
#[test]
fn random_noise_fields_are_watertight() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(99);
    for (trial, n) in [12usize, 20, 31].into_iter().enumerate() {
        let grid = GridSpec::cube([-1.0; 3], [1.0; 3], n);
        let mut values = vec![1.0f32; n * n * n];
        for k in 1..n - 1 {
            for j in 1..n - 1 {
                for i in 1..n - 1 {
                    values[(k * n + j) * n + i] = rng.random_range(-1.0f32..1.0);
                }
            }
        }
        let m = neus_aug::mesh::marching_cubes_values(&values, &grid, 0.0).unwrap();
        let r = TopologyReport::of(&m);
        assert!(r.faces > 1000);
        assert!(r.is_closed_manifold(), "noise trial {trial}: {r:?}");
        assert_eq!(r.unreferenced_vertices, 0);
        // χ is even for closed orientable surfaces.
        assert_eq!(r.euler_characteristic % 2, 0, "{r:?}");
    }
}

#[test]
fn surfaces_cut_by_the_box_have_boundary_edges_but_stay_manifold() {
    let grid = GridSpec::cube([-0.5; 3], [0.5; 3], 40);
    let m = mesh_of(Shape::named("sphere").unwrap(), &grid);
    let r = TopologyReport::of(&m);
    assert!(r.boundary_edges > 0, "{r:?}");
    assert_eq!((r.non_manifold_edges, r.misoriented_edges), (0, 0), "{r:?}");
}

#[test]
fn two_pass_refines_inside_the_padded_coarse_bounds() {
    let shape = Shape::named("torus").unwrap();
    let sdf = move |p: &[[f32; 3]]| shape.eval_batch(p);
    let opts = TwoPassOptions {
        coarse_res: 48,
        fine_res: 48,
        ..TwoPassOptions::default()
    };
    let out = extract_two_pass(&sdf, &opts).unwrap();
    let fine = out.fine_grid.expect("a refined pass");
    // The torus spans x, y in ±0.73 and z in ±0.21 (plus its offset): the refined box is much
    // smaller than [-1, 1]^3 along z, inside it, and contains the coarse mesh with padding.
    let coarse = marching_cubes(&sdf, &out.coarse_grid, &opts.mc).unwrap();
    assert_eq!(coarse.faces.len(), out.coarse_faces);
    let (lo, hi) = coarse.bounds().unwrap();
    let cell = out.coarse_grid.cell_size();
    for a in 0..3 {
        // 10 % of the extent, at least one coarse cell (z: 0.1·0.42 < 2/47).
        let pad = (0.1 * (hi[a] - lo[a])).max(cell[a]);
        assert!(
            (fine.min[a] - (lo[a] - pad).max(-1.0)).abs() < 1e-6,
            "axis {a}"
        );
        assert!(
            (fine.max[a] - (hi[a] + pad).min(1.0)).abs() < 1e-6,
            "axis {a}"
        );
    }
    assert!(fine.max[2] - fine.min[2] < 0.6);
    assert_eq!(fine.res, [48; 3]);
    // Smaller cells: more faces and vertices closer to the surface than the coarse pass.
    let err = |m: &TriMesh| {
        m.vertices
            .iter()
            .map(|v| shape.eval(*v).abs() as f64)
            .sum::<f64>()
            / m.vertices.len() as f64
    };
    assert!(out.mesh.faces.len() > coarse.faces.len());
    assert!(
        err(&out.mesh) < 0.7 * err(&coarse),
        "{} vs {}",
        err(&out.mesh),
        err(&coarse)
    );
    let r = TopologyReport::of(&out.mesh);
    assert!(
        r.is_closed_manifold() && r.euler_characteristic == 0,
        "{r:?}"
    );
}

#[test]
fn two_pass_of_an_sdf_without_surface_is_empty() {
    let opts = TwoPassOptions {
        coarse_res: 16,
        fine_res: 16,
        ..TwoPassOptions::default()
    };
    let out = extract_two_pass(&|p: &[[f32; 3]]| vec![1.0; p.len()], &opts).unwrap();
    assert_eq!(out.mesh, TriMesh::default());
    assert!(out.fine_grid.is_none());
}

#[test]
fn refined_box_is_padded_by_at_least_one_coarse_cell_and_clamped() {
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 21); // cell 0.1
    let opts = TwoPassOptions::default();
    // A flat mesh (zero extent along z) near the upper x bound.
    let m = TriMesh {
        vertices: vec![[0.2, 0.0, 0.3], [0.98, 0.5, 0.3], [0.5, -0.5, 0.3]],
        faces: vec![[0, 1, 2]],
    };
    let g = refined_grid(&m, &grid, &opts).unwrap();
    assert!(
        (g.min[2] - 0.2).abs() < 1e-6 && (g.max[2] - 0.4).abs() < 1e-6,
        "{g:?}"
    );
    assert_eq!(g.max[0], 1.0);
    assert!((g.min[0] - 0.2 + 0.1).abs() < 1e-6, "{g:?}");
    assert!(refined_grid(&TriMesh::default(), &grid, &opts).is_none());
}

#[test]
fn world_mapping_applies_scale_and_centre() {
    let mut m = TriMesh {
        vertices: vec![[0.5, -1.0, 0.25]],
        faces: vec![],
    };
    to_world(
        &mut m,
        &Normalization {
            scale: 200.0,
            center: [10.0, 20.0, 600.0],
        },
    );
    assert_eq!(m.vertices[0], [110.0, -180.0, 650.0]);
}
