//! Ground truth is right, checked against independent brute-force references (f64, no obvhs):
//! GT points lie on the mesh; every GT point is seen by some camera and the points left out are
//! not; masks agree with a re-projection of the mesh by a small rasteriser.

mod sim_common;

use nalgebra::Vector3;
use neus_aug::scene::Camera;
use neus_aug::sim::gt::{sample_surface, VERTEX_POINT};
use neus_aug::sim::render::sample_offsets;
use neus_aug::sim::{SceneDescription, SimScene};
use sim_common::small;
use std::collections::HashSet;

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn lerp3(a: V3, b: V3, c: V3, u: f64, v: f64) -> V3 {
    std::array::from_fn(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]))
}

/// Distance from `p` to triangle `abc` (Ericson, *Real-Time Collision Detection*, 5.1.5: the
/// closest point by Voronoi regions).
fn point_triangle_distance(p: V3, a: V3, b: V3, c: V3) -> f64 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    let q = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else {
        let bp = sub(p, b);
        let (d3, d4) = (dot(ab, bp), dot(ac, bp));
        if d3 >= 0.0 && d4 <= d3 {
            b
        } else {
            let vc = d1 * d4 - d3 * d2;
            if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                lerp3(a, b, c, d1 / (d1 - d3), 0.0)
            } else {
                let cp = sub(p, c);
                let (d5, d6) = (dot(ab, cp), dot(ac, cp));
                if d6 >= 0.0 && d5 <= d6 {
                    c
                } else {
                    let vb = d5 * d2 - d1 * d6;
                    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                        lerp3(a, b, c, 0.0, d2 / (d2 - d6))
                    } else {
                        let va = d3 * d6 - d5 * d4;
                        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
                            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                            std::array::from_fn(|k| b[k] + w * (c[k] - b[k]))
                        } else {
                            let denom = 1.0 / (va + vb + vc);
                            lerp3(a, b, c, vb * denom, vc * denom)
                        }
                    }
                }
            }
        }
    };
    dot(sub(p, q), sub(p, q)).sqrt()
}

/// Möller–Trumbore in f64, both sides: the hit distance along unit `d`, if any.
fn ray_triangle(o: V3, d: V3, a: V3, b: V3, c: V3) -> Option<f64> {
    let (e1, e2) = (sub(b, a), sub(c, a));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-14 {
        return None;
    }
    let s = sub(o, a);
    let u = dot(s, p) / det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(dot(e2, q) / det)
}

fn triangles(scene: &SimScene) -> Vec<[V3; 3]> {
    let m = &scene.mesh_world;
    m.faces
        .iter()
        .map(|f| f.map(|i| m.vertices[i as usize].map(|c| c as f64)))
        .collect()
}

/// Brute force: does a surface cross the segment from the camera to `p` at a distance from the
/// camera below `|p − C| − margin`?
fn blocked(tris: &[[V3; 3]], cam: &Camera, p: V3, margin: f64) -> bool {
    let c: V3 = cam.center.into();
    let to = sub(p, c);
    let dist = dot(to, to).sqrt();
    let d = to.map(|v| v / dist);
    tris.iter().any(|[a, b, cc]| {
        ray_triangle(c, d, *a, *b, *cc).is_some_and(|t| t > 0.0 && t < dist - margin)
    })
}

fn in_image(cam: &Camera, p: V3) -> bool {
    cam.project(&Vector3::from(p)).is_some_and(|(u, v, _)| {
        u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64
    })
}

/// Checks the ground truth of `desc` against the references, which accept occluders up to
/// `eps` mm before a point (the description's own `occlusion_eps_mm` unless a test overrides it).
fn check_ground_truth(desc: &SceneDescription, n_check: usize) {
    check_ground_truth_with(desc, n_check, desc.gt.occlusion_eps_mm)
}

fn check_ground_truth_with(desc: &SceneDescription, n_check: usize, eps: f64) {
    let scene = SimScene::prepare(desc).unwrap();
    let gt = scene.ground_truth();
    let tris = triangles(&scene);
    let name = &desc.name;
    assert!(gt.points.len() > 1000, "{name}: {} points", gt.points.len());
    assert!(
        gt.stats.visible < gt.stats.sampled,
        "{name}: nothing was hidden"
    );

    // 1. On the mesh.
    let step = (gt.points.len() / n_check).max(1);
    let mut worst: f64 = 0.0;
    for p in gt.points.iter().step_by(step) {
        let p = p.map(|c| c as f64);
        let d = tris
            .iter()
            .map(|[a, b, c]| point_triangle_distance(p, *a, *b, *c))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    assert!(
        worst < 1e-4,
        "{name}: a GT point is {worst:e} mm off the mesh"
    );

    // 2. Every GT point is seen by some camera. The reference tolerates occluders up to
    //    eps + 0.01 mm before the point (obvhs runs in f32, the reference in f64).
    for p in gt.points.iter().step_by(step) {
        let p = p.map(|c| c as f64);
        let seen = scene
            .cameras
            .iter()
            .any(|cam| in_image(cam, p) && !blocked(&tris, cam, p, eps + 0.01));
        assert!(seen, "{name}: GT point {p:?} is seen by no camera");
    }

    // 3. Samples left out are not seen: for every camera, outside the image, or behind a
    //    surface (with a tolerance eps − 0.01 mm), or on a triangle facing away (closed meshes).
    let kept: HashSet<[u32; 3]> = gt.points.iter().map(|p| p.map(f32::to_bits)).collect();
    let rejected: Vec<_> = sample_surface(&scene, desc.gt.spacing_mm)
        .into_iter()
        .filter(|s| !kept.contains(&s.p.map(f32::to_bits)))
        .collect();
    assert!(!rejected.is_empty());
    let rstep = (rejected.len() / n_check).max(1);
    for s in rejected.iter().step_by(rstep) {
        let p = s.p.map(|c| c as f64);
        for cam in &scene.cameras {
            let facing_away = scene.closed_oriented && s.face != VERTEX_POINT && {
                let [a, b, c] = tris[s.face as usize];
                dot(cross(sub(b, a), sub(c, a)), sub(cam.center.into(), p)) <= 0.0
            };
            assert!(
                !in_image(cam, p) || facing_away || blocked(&tris, cam, p, eps - 0.01),
                "{name}: left-out point {p:?} is visible from camera at {:?}",
                cam.center.as_slice()
            );
        }
    }
}

#[test]
fn ground_truth_of_the_default_scene() {
    check_ground_truth(&small("blob", 80, 60, 6, 1, 1.0), 150);
}

#[test]
fn ground_truth_of_thin_structures() {
    check_ground_truth(&small("thin", 80, 60, 6, 1, 0.5), 150);
}

#[test]
fn the_ground_truth_check_catches_occluded_points() {
    // Ground truth made with a 150 mm occlusion tolerance keeps points hidden behind the cup's
    // wall; the reference (0.02 mm) must reject it.
    let mut desc = small("cup", 80, 60, 6, 1, 2.0);
    desc.gt.occlusion_eps_mm = 150.0;
    let caught = std::panic::catch_unwind(|| check_ground_truth_with(&desc, 400, 0.02));
    assert!(caught.is_err(), "a wrong ground truth passed the check");
}

#[test]
fn ground_truth_of_blocks_and_cup() {
    check_ground_truth(&small("blocks", 80, 60, 6, 1, 2.0), 150);
    check_ground_truth(&small("cup", 80, 60, 6, 1, 1.0), 150);
}

/// Re-projects the mesh into `cam` and marks, per pixel and sample offset, whether the sample
/// point falls in a projected triangle: an independent rasteriser (edge functions in f64).
fn rasterise(tris: &[[V3; 3]], cam: &Camera, offsets: &[[f64; 2]]) -> Vec<Vec<bool>> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut hits = vec![vec![false; offsets.len()]; w * h];
    for t in tris {
        let Some(q) = t
            .iter()
            .map(|p| cam.project(&Vector3::from(*p)).map(|(u, v, _)| [u, v]))
            .collect::<Option<Vec<[f64; 2]>>>()
        else {
            continue;
        };
        let edge = |a: [f64; 2], b: [f64; 2], s: [f64; 2]| {
            (b[0] - a[0]) * (s[1] - a[1]) - (b[1] - a[1]) * (s[0] - a[0])
        };
        let x0 = q
            .iter()
            .map(|p| p[0])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let y0 = q
            .iter()
            .map(|p| p[1])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let x1 = (q
            .iter()
            .map(|p| p[0])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as usize)
            .min(w);
        let y1 = (q
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as usize)
            .min(h);
        for y in y0..y1 {
            for x in x0..x1 {
                for (k, o) in offsets.iter().enumerate() {
                    let s = [x as f64 + o[0], y as f64 + o[1]];
                    let e = [
                        edge(q[1], q[2], s),
                        edge(q[2], q[0], s),
                        edge(q[0], q[1], s),
                    ];
                    if e.iter().all(|&v| v >= 0.0) || e.iter().all(|&v| v <= 0.0) {
                        hits[y * w + x][k] = true;
                    }
                }
            }
        }
    }
    hits
}

fn check_masks(desc: &SceneDescription) {
    check_masks_against(desc, 0)
}

/// Compares view `i`'s mask with the re-projection into camera `i + shift` (0 in real checks).
fn check_masks_against(desc: &SceneDescription, shift: usize) {
    let scene = SimScene::prepare(desc).unwrap();
    let tris = triangles(&scene);
    let offsets = sample_offsets(desc.render.spp);
    for i in 0..scene.cameras.len() {
        let cam = &scene.cameras[(i + shift) % scene.cameras.len()];
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mask = scene.render_view(i).mask;
        let hits = rasterise(&tris, cam, &offsets);
        let reference: Vec<bool> = hits
            .iter()
            .map(|s| 2 * s.iter().filter(|&&b| b).count() > s.len())
            .collect();
        let boundary = |x: usize, y: usize| {
            let v = reference[y * w + x];
            (y.saturating_sub(1)..(y + 2).min(h)).any(|yy| {
                (x.saturating_sub(1)..(x + 2).min(w)).any(|xx| reference[yy * w + xx] != v)
            })
        };
        let n_boundary = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| boundary(x, y))
            .count();
        let covered = reference.iter().filter(|&&b| b).count();
        assert!(
            covered > w * h / 20,
            "{}: view {i} barely shows the object",
            desc.name
        );
        let mut mismatches = 0;
        for y in 0..h {
            for x in 0..w {
                let m = mask.data[y * w + x];
                assert!(m == 0.0 || m == 1.0, "mask value {m}");
                if (m == 1.0) != reference[y * w + x] {
                    assert!(
                        boundary(x, y),
                        "{}: view {i} mask differs from the re-projection at interior pixel ({x}, {y})",
                        desc.name
                    );
                    mismatches += 1;
                }
            }
        }
        assert!(
            mismatches <= 1 + n_boundary / 100,
            "{}: view {i}: {mismatches} mismatches on {n_boundary} boundary pixels",
            desc.name
        );
    }
}

#[test]
fn masks_agree_with_a_reprojection_of_the_mesh() {
    check_masks(&small("blob", 160, 120, 3, 1, 1.0));
    check_masks(&small("thin", 160, 120, 3, 4, 1.0));
    // The ground plane appears in the images but never in the masks.
    check_masks(&small("blocks", 160, 120, 3, 1, 1.0));
}

#[test]
fn the_mask_check_catches_a_wrong_view() {
    let desc = small("blob", 80, 60, 3, 1, 1.0);
    let caught = std::panic::catch_unwind(|| check_masks_against(&desc, 1));
    assert!(caught.is_err(), "masks of the wrong view passed the check");
}

/// The observation mask, voxel by voxel, against an independent f64 reference: a voxel is
/// observed iff it holds a GT point, or it lies within the band and its centre is above the
/// plane, outside the solid (ray-crossing parity, not orientation) and seen by a camera.
fn check_observation_mask(desc: &SceneDescription, n_check: usize) {
    use rand::{Rng, SeedableRng};
    let scene = SimScene::prepare(desc).unwrap();
    let gt = scene.ground_truth();
    let tris = triangles(&scene);
    let m = &gt.obs_mask;
    let (res, dilate) = (m.res, desc.gt.obs_dilate_mm);
    let surface: HashSet<[i64; 3]> = gt
        .points
        .iter()
        .map(|p| neus_aug::sim::gt::voxel_index(*p, m.bb[0], res))
        .collect();
    let r = (dilate / res).floor() as i64;
    let in_band = |v: [i64; 3]| {
        (-r..=r).any(|i| {
            (-r..=r).any(|j| {
                (-r..=r).any(|k| {
                    ((i * i + j * j + k * k) as f64) * res * res <= dilate * dilate
                        && surface.contains(&[v[0] + i, v[1] + j, v[2] + k])
                })
            })
        })
    };
    let dir = {
        let d = [0.123, 0.456, 0.881];
        let n = dot(d, d).sqrt();
        d.map(|x| x / n)
    };
    let inside = |c: V3| {
        tris.iter()
            .filter(|[a, b, cc]| ray_triangle(c, dir, *a, *b, *cc).is_some_and(|t| t > 0.0))
            .count()
            % 2
            == 1
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let (mut observed, mut unobserved, mut mismatches) = (0, 0, 0);
    while observed + unobserved < n_check {
        let v: [i64; 3] = std::array::from_fn(|k| rng.random_range(0..m.dims[k] as i64));
        let holds_point = surface.contains(&v);
        if !holds_point && !in_band(v) {
            continue;
        }
        let c: V3 = std::array::from_fn(|k| m.bb[0][k] + v[k] as f64 * res);
        let reference = holds_point
            || (gt.plane.eval(c) > 0.0
                && !inside(c)
                && scene.cameras.iter().any(|cam| {
                    in_image(cam, c) && !blocked(&tris, cam, c, desc.gt.occlusion_eps_mm)
                }));
        let got = m.get(v[0], v[1], v[2]);
        if got {
            observed += 1;
        } else {
            unobserved += 1;
        }
        if got != reference {
            mismatches += 1;
        }
    }
    assert!(
        observed > n_check / 10 && unobserved > n_check / 10,
        "{}: sample not mixed ({observed} observed, {unobserved} not)",
        desc.name
    );
    assert!(
        mismatches <= n_check / 100,
        "{}: {mismatches} of {n_check} band voxels disagree with the reference",
        desc.name
    );
}

#[test]
fn observation_mask_is_the_observed_volume() {
    check_observation_mask(&small("blob", 80, 60, 6, 1, 2.0), 150);
    check_observation_mask(&small("cup", 80, 60, 6, 1, 2.0), 150);
}
