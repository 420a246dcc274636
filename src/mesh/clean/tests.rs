use super::*;
use crate::mesh::{marching_cubes, sdf::Shape, GridSpec, McOptions};
use nalgebra::Matrix3;

fn shape_mesh(name: &str, res: usize) -> TriMesh {
    mesh_of(Shape::named(name).unwrap(), res)
}

/// Slow reference: components by repeated flood fill over a face adjacency list.
fn components_reference(mesh: &TriMesh) -> usize {
    let nf = mesh.faces.len();
    let mut seen = vec![false; nf];
    let mut n = 0;
    for s in 0..nf {
        if seen[s] {
            continue;
        }
        n += 1;
        let mut stack = vec![s];
        seen[s] = true;
        while let Some(f) = stack.pop() {
            for (g, sg) in seen.iter_mut().enumerate() {
                if !*sg && mesh.faces[f].iter().any(|v| mesh.faces[g].contains(v)) {
                    *sg = true;
                    stack.push(g);
                }
            }
        }
    }
    n
}

#[test]
fn components_match_flood_fill_and_small_ones_go() {
    let mut m = shape_mesh("two-spheres", 24);
    // A speck: one tiny triangle far away.
    let b = m.vertices.len() as u32;
    m.vertices
        .extend([[0.9, 0.9, 0.9], [0.901, 0.9, 0.9], [0.9, 0.901, 0.9]]);
    m.faces.push([b, b + 1, b + 2]);
    let (_, n) = face_components(&m);
    assert_eq!(n, components_reference(&m));
    assert_eq!(n, 3);
    let (out, rep) = clean_mesh(&m, &[], &[], &CleanOptions::default());
    assert_eq!(
        (
            rep.components_before,
            rep.components_after,
            rep.small_components_removed
        ),
        (3, 2, 1),
        "both spheres are real parts, the speck is not: {rep:?}"
    );
    assert_eq!(rep.faces_in_small_components, 1);
    assert_eq!(out.faces.len(), m.faces.len() - 1);
    assert_eq!(out.vertices.len(), m.vertices.len() - 3);
}

#[test]
fn unseen_components_and_the_cuts_specks_go() {
    // Sphere A (x > 0) half seen, sphere B (x < 0) with one seen face, and a copy of both
    // moved away, not seen at all.
    let mut m = shape_mesh("two-spheres", 24);
    let (nv, nf) = (m.vertices.len() as u32, m.faces.len());
    let (va, fa) = (m.vertices.clone(), m.faces.clone());
    m.vertices
        .extend(va.iter().map(|v| [v[0], v[1] + 1.5, v[2]]));
    m.faces.extend(fa.iter().map(|f| f.map(|i| i + nv)));
    let cx = |f: &[u32; 3]| centroid(&m, f).x;
    let in_c = |i: usize| i >= nf;
    let mut one_b = false;
    let seen: Vec<bool> = (0..m.faces.len())
        .map(|i| {
            let x = cx(&m.faces[i]);
            if in_c(i) {
                false
            } else if x > 0.43 {
                true
            } else if x < 0.0 && !one_b {
                one_b = true;
                true
            } else {
                false
            }
        })
        .collect();
    let n_seen_a = (0..nf).filter(|&i| cx(&m.faces[i]) > 0.43).count();
    let cut = split_unseen(&m, &seen, 0.02, SpeckRule::Piece);
    assert_eq!(
        (
            cut.unseen_components_removed,
            cut.faces_in_unseen_components
        ),
        (2, m.faces.len() - nf),
        "the copy's two spheres, never seen, leave the closed surface"
    );
    assert_eq!(cut.closed.faces.len(), nf, "spheres A and B stay whole");
    assert_eq!(face_components(&cut.closed).1, 2);
    assert_eq!(
        (cut.cut_specks_removed, cut.faces_in_cut_specks),
        (1, 1),
        "B's one seen face is a speck of the cut"
    );
    assert_eq!(cut.seen.faces.len(), n_seen_a);
    assert_eq!(cut.faces_unseen, m.faces.len() - n_seen_a - 1);
    // Share 0 keeps the speck; all seen keeps everything.
    assert_eq!(
        split_unseen(&m, &seen, 0.0, SpeckRule::Piece)
            .seen
            .faces
            .len(),
        n_seen_a + 1
    );
    let all = split_unseen(&m, &vec![true; m.faces.len()], 0.02, SpeckRule::Piece);
    assert_eq!(
        (
            all.seen.faces.len(),
            all.closed.faces.len(),
            all.faces_unseen
        ),
        (m.faces.len(), m.faces.len(), 0)
    );
}

#[test]
fn by_part_the_cut_keeps_a_small_seen_piece_of_a_part_and_drops_a_floaters_speck() {
    // Sphere A (x > 0): its far half seen, and apart from it the one face nearest the other
    // sphere, so the cut leaves A in two pieces. Sphere B (x < 0): one seen face, a floater.
    let m = shape_mesh("two-spheres", 24);
    let cx = |i: usize| centroid(&m, &m.faces[i]).x;
    let tip = (0..m.faces.len())
        .filter(|&i| cx(i) > 0.0)
        .min_by(|&i, &j| cx(i).total_cmp(&cx(j)))
        .unwrap();
    let b_face = (0..m.faces.len()).find(|&i| cx(i) < 0.0).unwrap();
    let seen: Vec<bool> = (0..m.faces.len())
        .map(|i| cx(i) > 0.43 || i == tip || i == b_face)
        .collect();
    let cap = (0..m.faces.len()).filter(|&i| cx(i) > 0.43).count();
    let (_, pieces) = face_components(&keep_faces(&m, &seen));
    assert_eq!(pieces, 3, "A's half, A's tip face and B's face");
    let piece = split_unseen(&m, &seen, 0.02, SpeckRule::Piece);
    assert_eq!(
        piece.seen.faces.len(),
        cap,
        "by piece both one-face pieces go"
    );
    assert_eq!(piece.cut_specks_removed, 2);
    let part = split_unseen(&m, &seen, 0.02, SpeckRule::Part);
    assert_eq!(
        part.seen.faces.len(),
        cap + 1,
        "by part A's tip stays, B's face goes"
    );
    assert_eq!((part.cut_specks_removed, part.faces_in_cut_specks), (1, 1));
    let kept = keep_faces(
        &m,
        &(0..m.faces.len())
            .map(|i| i != b_face && seen[i])
            .collect::<Vec<_>>(),
    );
    assert_eq!(
        part.seen.vertices, kept.vertices,
        "the same faces, in the input's order"
    );
    assert_eq!(part.seen.faces, kept.faces);
    assert_eq!(part.closed.faces.len(), piece.closed.faces.len());
    assert_eq!(part.faces_unseen, piece.faces_unseen);
    // Everything seen: nothing goes; share 0 keeps B's face too.
    let all = split_unseen(&m, &vec![true; m.faces.len()], 0.02, SpeckRule::Part);
    assert_eq!(all.seen.faces.len(), m.faces.len());
    assert_eq!(
        split_unseen(&m, &seen, 0.0, SpeckRule::Part)
            .seen
            .faces
            .len(),
        cap + 2
    );
}

#[test]
fn empty_mesh_cleans_to_empty() {
    let m = TriMesh {
        vertices: vec![],
        faces: vec![],
    };
    let (out, rep) = clean_mesh(&m, &[], &[], &CleanOptions::default());
    assert!(out.faces.is_empty());
    assert_eq!(rep.components_after, 0);
}

#[test]
fn dilation_matches_brute_force() {
    let (w, h) = (13, 9);
    let mut mask = GrayImage::new(w, h);
    for (i, v) in mask.data.iter_mut().enumerate() {
        *v = if (i * 7919) % 23 == 0 { 1.0 } else { 0.0 };
    }
    for r in [0, 1, 3] {
        let d = dilate_mask(&mask, r);
        for y in 0..h {
            for x in 0..w {
                let mut any = false;
                for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                    for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                        any |= mask.get(xx, yy) > 0.5;
                    }
                }
                assert_eq!(d[y * w + x], any, "r={r} ({x},{y})");
            }
        }
    }
}

#[test]
fn mask_culling_removes_what_the_silhouette_excludes() {
    // Camera on +z looking at the origin; mask = silhouette of the sphere only, so a
    // membrane disc beside it is culled and the sphere is kept.
    let (w, h) = (64usize, 64usize);
    let f = 60.0;
    let cam = Camera {
        k: Matrix3::new(f, 0.0, 32.0, 0.0, f, 32.0, 0.0, 0.0, 1.0),
        r: Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0),
        center: Vector3::new(0.0, 0.0, 3.0),
        width: w as u32,
        height: h as u32,
    };
    let sphere = Shape::Sphere {
        center: [0.0; 3],
        radius: 0.4,
    };
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 32);
    let mut m = marching_cubes(
        &|p: &[[f32; 3]]| sphere.eval_batch(p),
        &grid,
        &McOptions::default(),
    )
    .unwrap();
    let n_sphere = m.faces.len();
    let mut mask = GrayImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            let (o, d) = cam.ray(u, v);
            // Ray–sphere test.
            let b = o.dot(&d);
            let c = o.norm_squared() - 0.16;
            if b * b - c >= 0.0 {
                mask.data[y * w + x] = 1.0;
            }
        }
    }
    let b = m.vertices.len() as u32;
    m.vertices
        .extend([[0.7, 0.0, 0.0], [0.9, 0.0, 0.0], [0.8, 0.2, 0.0]]);
    m.faces.push([b, b + 1, b + 2]);
    let opts = CleanOptions {
        min_area_share: 0.0,
        ..Default::default()
    };
    let (out, rep) = clean_mesh(&m, &[(&cam, &mask)], &[&cam], &opts);
    assert_eq!(rep.faces_culled_by_masks, 1, "{rep:?}");
    assert_eq!(out.faces.len(), n_sphere);
    // Without masks the frustum rule runs instead: the side triangle is inside the image and
    // stays; a triangle behind the camera goes.
    let b = m.vertices.len() as u32;
    m.vertices
        .extend([[0.0, 0.0, 3.5], [0.1, 0.0, 3.5], [0.0, 0.1, 3.5]]);
    m.faces.push([b, b + 1, b + 2]);
    let (out, rep) = clean_mesh(&m, &[], &[&cam], &opts);
    assert_eq!(rep.faces_outside_all_views, 1, "{rep:?}");
    assert_eq!(rep.faces_culled_by_masks, 0);
    assert_eq!(out.faces.len(), n_sphere + 1);
}

/// A 64×64 camera at `eye` looking at the origin, 60° field of view.
fn camera_at(eye: [f64; 3]) -> Camera {
    let up = if eye[0].abs() + eye[1].abs() < 1e-9 {
        Vector3::new(0.0, 1.0, 0.0)
    } else {
        Vector3::new(0.0, 0.0, 1.0)
    };
    let f = 32.0 / (30f64.to_radians()).tan();
    crate::scene::camera::look_at(
        Vector3::from(eye),
        Vector3::zeros(),
        up,
        Matrix3::new(f, 0.0, 32.0, 0.0, f, 32.0, 0.0, 0.0, 1.0),
        64,
        64,
    )
}

fn centroid(m: &TriMesh, f: &[u32; 3]) -> Vector3<f64> {
    f.iter()
        .map(|&i| Vector3::from(m.vertices[i as usize].map(|x| x as f64)))
        .sum::<Vector3<f64>>()
        / 3.0
}

/// Slow reference of [`visibility_filter`]: every camera, every triangle, Möller–Trumbore in
/// f64 (Möller & Trumbore, "Fast, minimum storage ray-triangle intersection", JGT 1997).
fn visibility_reference(mesh: &TriMesh, cameras: &[&Camera], min_views: usize) -> Vec<bool> {
    let p = |i: u32| Vector3::from(mesh.vertices[i as usize].map(|x| x as f64));
    let hit = |o: Vector3<f64>, d: Vector3<f64>, f: &[u32; 3]| -> Option<f64> {
        let (a, b, c) = (p(f[0]), p(f[1]), p(f[2]));
        let (e1, e2) = (b - a, c - a);
        let q = d.cross(&e2);
        let det = e1.dot(&q);
        if det.abs() < 1e-14 {
            return None;
        }
        let s = o - a;
        let u = s.dot(&q) / det;
        let r = s.cross(&e1);
        let v = d.dot(&r) / det;
        let t = e2.dot(&r) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some(t)
    };
    mesh.faces
        .iter()
        .map(|f| {
            let c = centroid(mesh, f);
            let seen = cameras
                .iter()
                .filter(|cam| {
                    if pixel_of(cam, &c).is_none() {
                        return false;
                    }
                    let to = c - cam.center;
                    let dist = to.norm();
                    let d = to / dist;
                    let tmax = dist - OCCLUSION_EPS as f64;
                    !mesh
                        .faces
                        .iter()
                        .any(|g| hit(cam.center, d, g).is_some_and(|t| t >= 0.0 && t <= tmax))
                })
                .count();
            seen >= min_views
        })
        .collect()
}

#[test]
fn visibility_keeps_what_cameras_see_and_matches_the_brute_force_reference() {
    let m = shape_mesh("two-spheres", 20);
    // Front (+y), side (+x) and the far side (−y).
    let (front, side, back) = (
        camera_at([0.0, 3.0, 0.4]),
        camera_at([3.2, 0.2, 0.3]),
        camera_at([0.1, -3.0, -0.2]),
    );
    for (cams, k) in [
        (vec![&front], 1),
        (vec![&front, &side], 1),
        (vec![&front, &side], 2),
        (vec![&front, &side, &back], 2),
    ] {
        let fast = visibility_filter(&m, &cams, k);
        let slow = visibility_reference(&m, &cams, k);
        let differ = fast.iter().zip(&slow).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{} cameras, k = {k}", cams.len());
    }
    // One camera: a face is seen only if it faces the camera (outward normals of the marching
    // cubes, tested in `mesh::mcubes`), and the far sphere is hidden behind the near one where
    // they overlap in the image.
    let keep = visibility_filter(&m, &[&side], 1);
    let seen = keep.iter().filter(|k| **k).count();
    assert!(
        seen > 0 && seen < m.faces.len() / 2,
        "{seen} of {}",
        m.faces.len()
    );
    for (f, &k) in m.faces.iter().zip(&keep) {
        let c = centroid(&m, f);
        let p = |i: u32| Vector3::from(m.vertices[f[i as usize] as usize].map(|x| x as f64));
        let n = (p(1) - p(0)).cross(&(p(2) - p(0))).normalize();
        let facing = n.dot(&(side.center - c).normalize());
        if k {
            assert!(facing > -0.05, "a face turned away is kept ({facing})");
        }
        // The near sphere (centre x = 0.43) is convex and nothing stands before it.
        if c.x > 0.43 && facing > 0.2 {
            assert!(
                k,
                "a face of the near sphere that faces the camera is culled"
            );
        }
    }
    // The sphere at x = −0.41 (radius 0.33) is hidden from the side camera by the one at
    // x = +0.43 (radius 0.29) along the x axis.
    let hidden = m.faces.iter().zip(&keep).any(|(f, &k)| {
        let c = centroid(&m, f);
        k && c.x < -0.2 && c.y.abs() < 0.1 && c.z.abs() < 0.1
    });
    assert!(!hidden, "a face behind the near sphere is kept");
    // No cameras or k = 0: nothing is culled; an empty mesh stays empty.
    assert_eq!(cull_unseen(&m, &[], 2, 0.0).1, 0);
    assert_eq!(cull_unseen(&m, &[&front], 0, 0.0).1, 0);
    let empty = TriMesh {
        vertices: vec![],
        faces: vec![],
    };
    assert!(visibility_filter(&empty, &[&front], 1).is_empty());
    // Two views asked of one camera: nothing is seen twice.
    let (out, n) = cull_unseen(&m, &[&front], 2, 0.0);
    assert_eq!((out.faces.len(), n), (0, m.faces.len()));
}

#[test]
fn growth_by_distance_matches_brute_force() {
    let m = shape_mesh("torus", 16);
    // Seen: the faces with x > 0.2.
    let seen: Vec<bool> = m.faces.iter().map(|f| centroid(&m, f).x > 0.2).collect();
    for margin in [0.0, 0.05, 0.3] {
        let fast = grow_by_distance(&m, &seen, margin);
        let kept: Vec<Vector3<f64>> = m
            .faces
            .iter()
            .zip(&seen)
            .filter(|(_, &s)| s)
            .map(|(f, _)| centroid(&m, f))
            .collect();
        for (i, f) in m.faces.iter().enumerate() {
            let c = centroid(&m, f);
            let near = kept.iter().any(|k| (k - c).norm() <= margin);
            assert_eq!(fast[i], seen[i] || near, "face {i}, margin {margin}");
        }
        if margin > 0.0 {
            assert!(fast.iter().filter(|k| **k).count() > kept.len());
        }
    }
    // Nothing seen: nothing to grow from.
    let none = vec![false; m.faces.len()];
    assert_eq!(grow_by_distance(&m, &none, 1.0), none);
}

#[test]
fn visibility_cut_keeps_a_closed_cameras_side_and_drops_the_unseen_back() {
    // A sphere seen from a ring of cameras above its equator: the cut keeps the upper
    // part (an open cap with one boundary loop) and drops the lower one, as the simulator's
    // ground truth keeps only points some camera sees.
    let m = shape_mesh("sphere", 24);
    let ring: Vec<Camera> = (0..8)
        .map(|i| {
            let a = i as f64 * std::f64::consts::PI / 4.0;
            camera_at([3.0 * a.cos(), 3.0 * a.sin(), 2.0])
        })
        .collect();
    let cams: Vec<&Camera> = ring.iter().collect();
    let (cut, n) = cull_unseen(&m, &cams, 2, 0.0);
    assert!(n > 0 && !cut.faces.is_empty());
    let topo = crate::mesh::TopologyReport::of(&cut);
    assert_eq!(
        (topo.components, topo.boundary_loops, topo.genus),
        (1, 1, 0)
    );
    // Everything kept is above the lowest point a camera sees: from elevation atan(2/3) =
    // 33.7°, a camera sees the points within acos(0.61/√13) = 80.3° of its direction (seen
    // from the centre), down to latitude 33.7° − 80.3° = −46.6°, and only under itself.
    let c0 = Vector3::new(0.031, -0.047, 0.013);
    for f in &cut.faces {
        let d = centroid(&cut, f) - c0;
        let lat = (d.z / d.norm()).asin().to_degrees();
        assert!(lat > -47.0, "a face at latitude {lat:.1}° is kept");
    }
    // And the top is kept whole.
    assert!(cut.faces.len() > m.faces.len() / 2);
}

fn mesh_of(shape: Shape, res: usize) -> TriMesh {
    shape.mesh_in_unit_cube(res)
}

fn merged(parts: &[TriMesh]) -> TriMesh {
    let mut m = TriMesh {
        vertices: vec![],
        faces: vec![],
    };
    for p in parts {
        let b = m.vertices.len() as u32;
        m.vertices.extend(&p.vertices);
        m.faces.extend(p.faces.iter().map(|f| f.map(|i| i + b)));
    }
    m
}

/// Slow reference of "inside": the parity of the crossings of a ray (Möller–Trumbore, every
/// triangle), along an arbitrary direction that no test point's ray grazes an edge with.
fn inside_by_parity(mesh: &TriMesh, p: Vector3<f64>) -> bool {
    let d = Vector3::new(0.5377, 0.8621, 0.3188).normalize();
    let mut crossings = 0;
    for f in &mesh.faces {
        let v = |i: u32| Vector3::from(mesh.vertices[i as usize].map(|x| x as f64));
        let (a, b, c) = (v(f[0]), v(f[1]), v(f[2]));
        let (e1, e2) = (b - a, c - a);
        let h = d.cross(&e2);
        let det = e1.dot(&h);
        if det.abs() < 1e-14 {
            continue;
        }
        let s = p - a;
        let u = s.dot(&h) / det;
        let q = s.cross(&e1);
        let w = d.dot(&q) / det;
        let t = e2.dot(&q) / det;
        if (0.0..=1.0).contains(&u) && w >= 0.0 && u + w <= 1.0 && t > 0.0 {
            crossings += 1;
        }
    }
    crossings % 2 == 1
}

#[test]
fn solid_angle_and_winding_number_match_references() {
    // An octant's triangle subtends an eighth of the sphere; reversed, minus that.
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let o = solid_angle(x, y, z);
    assert!((o - std::f64::consts::FRAC_PI_2).abs() < 1e-14, "{o}");
    assert!((solid_angle(x, z, y) + o).abs() < 1e-14);
    // In the triangle's plane (outside it), and degenerate: 0, finite.
    assert_eq!(solid_angle(x, 2.0 * x, 3.0 * x), 0.0);
    assert_eq!(solid_angle(x + y, 2.0 * x + y, 3.0 * x + 2.0 * y), 0.0);
    // Winding number of a marching-cubes torus against ray parity at random points, and at
    // the points that matter: the hole's centre (outside) and the tube's core (inside).
    let torus = mesh_of(Shape::named("torus").unwrap(), 40);
    let all: Vec<usize> = (0..torus.faces.len()).collect();
    let c = Vector3::new(0.017, 0.023, -0.011);
    let hole = winding_number(&torus, &all, c);
    let core = winding_number(&torus, &all, c + Vector3::new(0.52, 0.0, 0.0));
    assert!(hole.abs() < 1e-6, "{hole}");
    assert!((core.abs() - 1.0).abs() < 1e-6, "{core}");
    let mut rng = rand_pcg::Pcg64Mcg::new(7);
    use rand::Rng;
    let mut n_in = 0;
    for _ in 0..200 {
        let p = Vector3::from_fn(|_, _| rng.random_range(-0.9..0.9));
        let w = winding_number(&torus, &all, p);
        assert!(
            (w.abs() - w.abs().round()).abs() < 1e-6,
            "closed mesh: integer winding number, got {w} at {p:?}"
        );
        let inside = w.abs() > 0.5;
        assert_eq!(inside, inside_by_parity(&torus, p), "{p:?}: {w}");
        n_in += inside as usize;
    }
    assert!(n_in > 10 && n_in < 190, "the test needs both sides: {n_in}");
}

#[test]
fn enclosed_components_go_and_parts_in_a_hole_stay() {
    let t = Shape::named("torus").unwrap();
    let Shape::Torus { center, major, .. } = t else {
        unreachable!()
    };
    // A ball in the hole (a real part beside the ring) and a bubble inside the tube (a cavity
    // no camera sees). Both pass the area rule: 6.6 % and 2.9 % of the torus's area.
    let ball = Shape::Sphere {
        center,
        radius: 0.15,
    };
    let bubble = Shape::Sphere {
        center: [center[0] + major, center[1], center[2]],
        radius: 0.1,
    };
    let m = merged(&[mesh_of(t, 48), mesh_of(ball, 48), mesh_of(bubble, 48)]);
    let n_ring_ball = mesh_of(t, 48).faces.len() + mesh_of(ball, 48).faces.len();
    let (out, rep) = clean_mesh(&m, &[], &[], &CleanOptions::default());
    assert_eq!(
        (
            rep.components_before,
            rep.small_components_removed,
            rep.enclosed_components_removed,
            rep.components_after
        ),
        (3, 0, 1, 2),
        "{rep:?}"
    );
    assert_eq!(out.faces.len(), n_ring_ball);
    assert_eq!(
        rep.faces_in_enclosed_components,
        m.faces.len() - n_ring_ball
    );
    // The rule is a switch.
    let keep_all = CleanOptions {
        remove_enclosed: false,
        ..Default::default()
    };
    let (out, rep) = clean_mesh(&m, &[], &[], &keep_all);
    assert_eq!((out.faces.len(), rep.components_after), (m.faces.len(), 3));
    // Side by side, nothing is enclosed.
    let (_, removed) = enclosed_component_filter(&shape_mesh("two-spheres", 32));
    assert_eq!(removed, 0);
}
