//! Mesh clean-up after extraction: mask culling, removal of small floating components and of
//! components enclosed by another, and culling of what no camera sees.
//!
//! Four rules, applied in this order to the mesh in **normalised space** (cameras of the training
//! views, DESIGN §3):
//!
//! 1. **Mask culling** (when the training views have masks): a vertex is removed when some training
//!    view sees it inside its image but outside that view's object mask dilated by
//!    `dilate_px` pixels. The object projects inside its silhouette in every view whatever the
//!    occlusion, so the rule never removes true surface unless a mask is wrong by more than the
//!    dilation. This is the culling that the DTU evaluations of the NeuS successors apply before
//!    scoring (MonoSDF / NeuralWarp `cull_mesh` style: project, test the dilated mask, drop faces
//!    that touch a culled vertex); NeuS itself evaluates its raw mesh.
//!    Without masks (`data.masks = false`), the frustum rule replaces it: a vertex that no
//!    training view sees inside its image is removed (what no camera constrains is not evidence
//!    of a surface; the same culling as above with an all-object mask).
//! 2. **Small components**: faces are grouped into connected components (through shared vertices)
//!    and a component whose surface area is below `min_area_share` × the largest component's area
//!    is removed. Separate real parts of an object have areas of the same order as the main part;
//!    floaters are small. The default share (0.02) keeps every component of every built-in
//!    ground-truth mesh (tested) and removes specks.
//! 3. **Enclosed components**: a component that lies inside another, larger one (every sampled
//!    vertex has a generalised winding number of magnitude above ½ with respect to the larger
//!    component's triangles; Jacobson, Kavan & Sorkine-Hornung, *Robust Inside-Outside
//!    Segmentation using Generalized Winding Numbers*, SIGGRAPH 2013) is removed. Such a shell is
//!    a cavity inside the object: no camera outside the object sees it, so no image supports it,
//!    and DTU's scans hold only visible surface. Seen on the torus (`results/geometry/
//!    holes-ia-2026-11-24`): closed bubbles inside the tube, 2 % of the surface, that the area
//!    rule keeps. A part that sits in another's hole (a ball inside a ring) has winding number 0
//!    there and stays (tested). The winding number does not need the larger component to be
//!    closed (mask culling may have cut it) and does not depend on its face orientation.
//!
//! 4. **Unseen faces** ([`cull_unseen`], run by `reconstruct` after the three rules above when
//!    `mesh.clean_min_visible_views > 0`): a face is kept when at least that many training
//!    cameras see its centroid, in their image and not hidden by the mesh itself (one ray per
//!    camera through the mesh's own BVH). What no camera sees (the underside of an object on a
//!    turntable, the back of a plaque shot from the front) has no image evidence: the SDF there
//!    is whatever the initialisation left, and it costs accuracy where it pokes into the
//!    observed volume (`results/geometry/knobs-2026-11-25`). The rule mirrors how the ground
//!    truth is made: DTU's structured-light scans, and the simulator's points (`sim::gt`), hold
//!    only surface that some camera sees. Two views, the default, is the least that
//!    triangulates a point; it is the default of NeuralWarp's triangle filter (Darmon et al.,
//!    CVPR 2022, `evaluation/mesh_filtering.py`, `visible_mask` with `--min_nb_visible 2`),
//!    which rasterises the mesh in each view where this casts rays. The result is an open
//!    surface; `reconstruct` keeps the closed one beside it (`mesh_closed.ply`) and measures the
//!    genus on that. An optional margin ([`grow_by_distance`], `mesh.clean_visible_margin_mm`,
//!    default 0) keeps faces near a seen one as well: surface that the truth shows to a single
//!    camera at 85–90° (a silhouette rim) is lost without it, but the unseen bulges it is meant
//!    to remove start right at the seen edges, so any margin keeps their worst part (blob s0:
//!    0.671 mm at 0 against 0.615 at 4 mm; relief 0.538 against 0.708,
//!    `results/geometry/visible-2026-11-25`).
//!    Two follow-ups ([`split_unseen`]): a component of the closed surface of which no face is
//!    seen is removed from the closed surface as well (a floater behind the object, which rules
//!    1–3 keep when it is large and outside every other component), and rule 2 runs again on
//!    the seen surface, which the cut can leave with specks (`results/geometry/seed2-2026-11-26`).
//!
//! Faces that lose a vertex are removed; vertices no face uses are dropped and the rest renumbered
//! in their original order, so the result is deterministic.

use super::topology::UnionFind;
use super::TriMesh;
use crate::scene::camera::Camera;
use crate::scene::image::GrayImage;
use nalgebra::Vector3;
use serde::Serialize;

/// Settings of [`clean_mesh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CleanOptions {
    /// Remove components below this share of the largest component's area (`0` keeps all).
    pub min_area_share: f64,
    /// Cull by the training masks (when the views have masks).
    pub mask_cull: bool,
    /// Dilation of the masks in pixels (square window of radius `dilate_px`) before culling.
    pub dilate_px: usize,
    /// Without masks: cull what no training view sees inside its image.
    pub frustum_cull: bool,
    /// Remove components enclosed by a larger component (rule 3 of the module docs).
    pub remove_enclosed: bool,
}

impl Default for CleanOptions {
    fn default() -> Self {
        Self {
            min_area_share: 0.02,
            mask_cull: true,
            dilate_px: 4,
            frustum_cull: true,
            remove_enclosed: true,
        }
    }
}

/// What [`clean_mesh`] removed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(default)]
pub struct CleanReport {
    /// Connected components before clean-up.
    pub components_before: usize,
    /// Connected components after clean-up.
    pub components_after: usize,
    /// Faces before clean-up.
    pub faces_before: usize,
    /// Faces removed by mask culling.
    pub faces_culled_by_masks: usize,
    /// Faces removed because no training view sees them inside its image (no masks).
    pub faces_outside_all_views: usize,
    /// Faces removed with small components.
    pub faces_in_small_components: usize,
    /// Components removed as small.
    pub small_components_removed: usize,
    /// Faces removed with components enclosed by a larger component.
    pub faces_in_enclosed_components: usize,
    /// Components removed as enclosed by a larger component.
    pub enclosed_components_removed: usize,
    /// Faces removed by [`cull_unseen`] (rule 4; `0` when it did not run).
    pub faces_unseen: usize,
    /// Components of the closed surface of which no face is seen, removed from it too (rule 4's
    /// first follow-up, [`split_unseen`]; `components_after` counts what is left), and their faces.
    pub unseen_components_removed: usize,
    pub faces_in_unseen_components: usize,
    /// Specks of the seen surface below `min_area_share` of its largest component, removed from
    /// the scored mesh (rule 4's second follow-up), and their faces.
    pub cut_specks_removed: usize,
    pub faces_in_cut_specks: usize,
    /// Components of the mesh [`cull_unseen`] left (equal to `components_after` when it did not
    /// run): cutting away the unseen side can split a closed surface into visible patches.
    pub components_seen: usize,
}

/// Connected components of the faces (through shared vertices): a label in `0..n` per face,
/// numbered in order of first appearance, and `n`.
pub fn face_components(mesh: &TriMesh) -> (Vec<u32>, usize) {
    let mut uf = UnionFind::new(mesh.vertices.len());
    for f in &mesh.faces {
        uf.union(f[0] as usize, f[1] as usize);
        uf.union(f[1] as usize, f[2] as usize);
    }
    let mut label = vec![u32::MAX; mesh.vertices.len()];
    let mut n = 0u32;
    let labels = mesh
        .faces
        .iter()
        .map(|f| {
            let r = uf.find(f[0] as usize);
            if label[r] == u32::MAX {
                label[r] = n;
                n += 1;
            }
            label[r]
        })
        .collect();
    (labels, n as usize)
}

/// Area of one triangle (f64).
fn face_area(mesh: &TriMesh, f: &[u32; 3]) -> f64 {
    let p = |i: u32| Vector3::from(mesh.vertices[i as usize].map(|x| x as f64));
    let (a, b, c) = (p(f[0]), p(f[1]), p(f[2]));
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Total area of the mesh (its units squared, f64).
pub fn surface_area(mesh: &TriMesh) -> f64 {
    mesh.faces.iter().map(|f| face_area(mesh, f)).sum()
}

/// The mesh restricted to the faces with `keep[i]`, unused vertices dropped (order kept).
pub fn keep_faces(mesh: &TriMesh, keep: &[bool]) -> TriMesh {
    assert_eq!(keep.len(), mesh.faces.len(), "one flag per face");
    let mut used = vec![false; mesh.vertices.len()];
    for (f, _) in mesh.faces.iter().zip(keep).filter(|(_, &k)| k) {
        for &i in f {
            used[i as usize] = true;
        }
    }
    let mut map = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    for (i, v) in mesh.vertices.iter().enumerate() {
        if used[i] {
            map[i] = vertices.len() as u32;
            vertices.push(*v);
        }
    }
    let faces = mesh
        .faces
        .iter()
        .zip(keep)
        .filter(|(_, &k)| k)
        .map(|(f, _)| f.map(|i| map[i as usize]))
        .collect();
    TriMesh { vertices, faces }
}

/// Per face: whether its component's area reaches `min_area_share` of the largest component's.
/// Also returns the number of components and how many were dropped.
pub fn small_component_filter(mesh: &TriMesh, min_area_share: f64) -> (Vec<bool>, usize, usize) {
    let (labels, n) = face_components(mesh);
    let mut area = vec![0.0f64; n];
    for (f, &l) in mesh.faces.iter().zip(&labels) {
        area[l as usize] += face_area(mesh, f);
    }
    let largest = area.iter().cloned().fold(0.0, f64::max);
    let keep_comp: Vec<bool> = area
        .iter()
        .map(|&a| a >= min_area_share * largest)
        .collect();
    let dropped = keep_comp.iter().filter(|k| !**k).count();
    (
        labels.iter().map(|&l| keep_comp[l as usize]).collect(),
        n,
        dropped,
    )
}

/// Solid angle (steradians, signed by the triangle's orientation) that the triangle `a b c`
/// subtends at the origin, with `a`, `b`, `c` relative to the point: Van Oosterom & Strackee
/// (IEEE Trans. Biomed. Eng. 30(2), 1983), `tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| +
/// (a·c)|b| + (b·c)|a|)`, taken with `atan2` so that the whole range `(−2π, 2π)` comes out. A
/// degenerate triangle, or a point on the triangle's plane outside it, subtends 0.
pub fn solid_angle(a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>) -> f64 {
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let num = a.dot(&b.cross(&c));
    let den = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
    if num == 0.0 && den <= 0.0 {
        // On the plane (or a vertex): no finite solid angle to speak of; atan2(0, −x) would
        // give ±2π by the sign of zero.
        return 0.0;
    }
    2.0 * num.atan2(den)
}

/// Generalised winding number of the point `p` with respect to the faces `faces` of `mesh`: the
/// sum of their solid angles at `p` over 4π (Jacobson et al. 2013). ±1 inside a closed surface
/// (the sign is the faces' orientation), 0 outside, fractional near holes of an open one.
pub fn winding_number(mesh: &TriMesh, faces: &[usize], p: Vector3<f64>) -> f64 {
    let v = |i: u32| Vector3::from(mesh.vertices[i as usize].map(|x| x as f64)) - p;
    let sum: f64 = faces
        .iter()
        .map(|&f| {
            let t = mesh.faces[f];
            solid_angle(v(t[0]), v(t[1]), v(t[2]))
        })
        .sum();
    sum / (4.0 * std::f64::consts::PI)
}

/// Vertices of a component sampled for the enclosure test (evenly over its faces' first
/// vertices).
const ENCLOSURE_SAMPLES: usize = 16;

/// Per face: whether its component is kept by the enclosure rule (rule 3 of the module docs),
/// and the number of components removed. A component is enclosed when some component of larger
/// area, whose bounding box contains its own, has a winding number of magnitude above ½ at each
/// of up to [`ENCLOSURE_SAMPLES`] of its vertices.
pub fn enclosed_component_filter(mesh: &TriMesh) -> (Vec<bool>, usize) {
    use rayon::prelude::*;
    let (labels, n) = face_components(mesh);
    let mut faces_of = vec![Vec::new(); n];
    let mut area = vec![0.0f64; n];
    let mut lo = vec![[f32::INFINITY; 3]; n];
    let mut hi = vec![[f32::NEG_INFINITY; 3]; n];
    for (i, (f, &l)) in mesh.faces.iter().zip(&labels).enumerate() {
        let l = l as usize;
        faces_of[l].push(i);
        area[l] += face_area(mesh, f);
        for &v in f {
            let x = mesh.vertices[v as usize];
            for a in 0..3 {
                lo[l][a] = lo[l][a].min(x[a]);
                hi[l][a] = hi[l][a].max(x[a]);
            }
        }
    }
    let inside_box =
        |c: usize, d: usize| (0..3).all(|a| lo[d][a] <= lo[c][a] && hi[c][a] <= hi[d][a]);
    let enclosed: Vec<bool> = (0..n)
        .map(|c| {
            let fc = &faces_of[c];
            let step = fc.len().div_ceil(ENCLOSURE_SAMPLES).max(1);
            let samples: Vec<Vector3<f64>> = fc
                .iter()
                .step_by(step)
                .map(|&f| Vector3::from(mesh.vertices[mesh.faces[f][0] as usize].map(|x| x as f64)))
                .collect();
            (0..n).any(|d| {
                d != c
                    && area[d] > area[c]
                    && inside_box(c, d)
                    && samples
                        .par_iter()
                        .all(|&p| winding_number(mesh, &faces_of[d], p).abs() > 0.5)
            })
        })
        .collect();
    let removed = enclosed.iter().filter(|e| **e).count();
    (
        labels.iter().map(|&l| !enclosed[l as usize]).collect(),
        removed,
    )
}

/// A mask dilated by a square window of radius `r` pixels (object where `> 0.5`), as booleans
/// `height × width` row-major. Separable running maximum, `O(width·height)` per axis.
pub fn dilate_mask(mask: &GrayImage, r: usize) -> Vec<bool> {
    let (w, h) = (mask.width, mask.height);
    let on: Vec<bool> = mask.data.iter().map(|&v| v > 0.5).collect();
    let run = |src: &[bool], len: usize, stride: usize, count: usize, step: usize| {
        // For each of `count` lines (start `j·step`), OR over a window of ±r along `stride`.
        let mut out = vec![false; src.len()];
        for j in 0..count {
            let base = j * step;
            // Prefix counts of "on" along the line.
            let mut pre = vec![0u32; len + 1];
            for i in 0..len {
                pre[i + 1] = pre[i] + src[base + i * stride] as u32;
            }
            for i in 0..len {
                let lo = i.saturating_sub(r);
                let hi = (i + r + 1).min(len);
                out[base + i * stride] = pre[hi] > pre[lo];
            }
        }
        out
    };
    let rows = run(&on, w, 1, h, w);
    run(&rows, h, w, w, 1)
}

/// Per face: kept unless one of its vertices is seen by some view inside the image but outside
/// that view's dilated mask (module docs, rule 1). `views` pairs each camera (normalised space)
/// with its mask at the camera's resolution.
pub fn mask_cull_filter(
    mesh: &TriMesh,
    views: &[(&Camera, &GrayImage)],
    dilate_px: usize,
) -> Vec<bool> {
    let dilated: Vec<Vec<bool>> = views
        .iter()
        .map(|(_, m)| dilate_mask(m, dilate_px))
        .collect();
    // Culled: some view sees the vertex inside its image, outside the dilated mask.
    faces_with_all_vertices(mesh, |x| {
        !views.iter().zip(&dilated).any(|((cam, m), d)| {
            pixel_of(cam, x)
                .is_some_and(|(px, py)| px < m.width && py < m.height && !d[py * m.width + px])
        })
    })
}

/// The pixel `(x, y)` whose square holds the projection of `x` (normalised space), `None` when
/// the point is behind the camera or outside its image.
pub(crate) fn pixel_of(cam: &Camera, x: &Vector3<f64>) -> Option<(usize, usize)> {
    let (u, v, _) = cam.project(x)?;
    (u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64)
        .then(|| (u.floor() as usize, v.floor() as usize))
}

/// Per face: whether `keep` holds for each of its three vertices.
fn faces_with_all_vertices(mesh: &TriMesh, keep: impl Fn(&Vector3<f64>) -> bool) -> Vec<bool> {
    let kept: Vec<bool> = mesh
        .vertices
        .iter()
        .map(|v| keep(&Vector3::from(v.map(|c| c as f64))))
        .collect();
    mesh.faces
        .iter()
        .map(|f| f.iter().all(|&i| kept[i as usize]))
        .collect()
}

/// Per face: kept when each of its vertices projects inside the image of at least one camera
/// (normalised space, in front of the camera).
pub fn frustum_filter(mesh: &TriMesh, cameras: &[&Camera]) -> Vec<bool> {
    faces_with_all_vertices(mesh, |x| {
        cameras.iter().any(|cam| pixel_of(cam, x).is_some())
    })
}

/// Distance (normalised units) by which an occluder must lie in front of a face's centroid to
/// hide it: 1e-3 is a quarter of a 512³ marching-cubes voxel over `[-1, 1]³` and well above the
/// f32 error of the intersection distance at camera range (about 1e-6·t).
const OCCLUSION_EPS: f32 = 1e-3;

/// Per face: whether at least `min_views` of `cameras` (normalised space) see it: its centroid
/// projects inside the camera's image, in front of it, and no face of `mesh` crosses the line of
/// sight more than [`OCCLUSION_EPS`] before the centroid (module docs, rule 4). Faces are
/// independent, so the result does not depend on the thread count.
pub fn visibility_filter(mesh: &TriMesh, cameras: &[&Camera], min_views: usize) -> Vec<bool> {
    use glam::Vec3A;
    use obvhs::triangle::Triangle;
    use rayon::prelude::*;
    if min_views == 0 {
        return vec![true; mesh.faces.len()];
    }
    let v = |i: u32| Vec3A::from(mesh.vertices[i as usize]);
    let tris: Vec<Triangle> = mesh
        .faces
        .iter()
        .map(|f| Triangle {
            v0: v(f[0]),
            v1: v(f[1]),
            v2: v(f[2]),
        })
        .collect();
    if tris.is_empty() {
        return Vec::new();
    }
    let tracer = crate::sim::setup::Tracer::new(&tris);
    let centers: Vec<Vec3A> = cameras
        .iter()
        .map(|c| Vec3A::new(c.center.x as f32, c.center.y as f32, c.center.z as f32))
        .collect();
    tris.par_iter()
        .map(|t| {
            let c = (t.v0 + t.v1 + t.v2) / 3.0;
            let cd = Vector3::new(c.x as f64, c.y as f64, c.z as f64);
            let mut seen = 0;
            for (cam, &o) in cameras.iter().zip(&centers) {
                if pixel_of(cam, &cd).is_none() {
                    continue;
                }
                let to = c - o;
                let dist = to.length();
                let tmax = dist - OCCLUSION_EPS;
                if tmax <= 0.0 || !tracer.occluded(o, to / dist, 0.0, tmax) {
                    seen += 1;
                    if seen >= min_views {
                        return true;
                    }
                }
            }
            false
        })
        .collect()
}

/// Applies the clean-up rules (module docs) and reports what they removed. `views` pairs the
/// training cameras with their masks; `cameras` are all training cameras, used by the frustum
/// rule when `views` is empty (no masks). With neither, only the component rule runs.
pub fn clean_mesh(
    mesh: &TriMesh,
    views: &[(&Camera, &GrayImage)],
    cameras: &[&Camera],
    opts: &CleanOptions,
) -> (TriMesh, CleanReport) {
    let (_, components_before) = face_components(mesh);
    let mut report = CleanReport {
        components_before,
        faces_before: mesh.faces.len(),
        ..Default::default()
    };
    let culled = if opts.mask_cull && !views.is_empty() {
        let keep = mask_cull_filter(mesh, views, opts.dilate_px);
        let m = keep_faces(mesh, &keep);
        report.faces_culled_by_masks = mesh.faces.len() - m.faces.len();
        m
    } else if opts.frustum_cull && !cameras.is_empty() {
        let keep = frustum_filter(mesh, cameras);
        let m = keep_faces(mesh, &keep);
        report.faces_outside_all_views = mesh.faces.len() - m.faces.len();
        m
    } else {
        mesh.clone()
    };
    let (keep, _, dropped) = small_component_filter(&culled, opts.min_area_share);
    let out = keep_faces(&culled, &keep);
    report.faces_in_small_components = culled.faces.len() - out.faces.len();
    report.small_components_removed = dropped;
    let out = if opts.remove_enclosed {
        let (keep, removed) = enclosed_component_filter(&out);
        let m = keep_faces(&out, &keep);
        report.faces_in_enclosed_components = out.faces.len() - m.faces.len();
        report.enclosed_components_removed = removed;
        m
    } else {
        out
    };
    report.components_after = face_components(&out).1;
    report.components_seen = report.components_after;
    (out, report)
}

/// Per face: whether its centroid lies within `margin` (mesh units) of the centroid of a face
/// with `seen`, or it has `seen` itself. Nearest neighbours on a k-d tree
/// (`dtu_eval::nn::PointTree`).
pub fn grow_by_distance(mesh: &TriMesh, seen: &[bool], margin: f64) -> Vec<bool> {
    assert_eq!(seen.len(), mesh.faces.len(), "one flag per face");
    let centroid = |f: &[u32; 3]| -> [f32; 3] {
        let p = |i: u32| mesh.vertices[i as usize];
        let (a, b, c) = (p(f[0]), p(f[1]), p(f[2]));
        std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0)
    };
    let kept: Vec<[f32; 3]> = mesh
        .faces
        .iter()
        .zip(seen)
        .filter(|(_, &s)| s)
        .map(|(f, _)| centroid(f))
        .collect();
    if margin <= 0.0 || kept.is_empty() || kept.len() == seen.len() {
        return seen.to_vec();
    }
    let Ok(tree) = dtu_eval::nn::PointTree::new(&kept) else {
        // Non-finite vertices: no growth (the flags stand as they are).
        return seen.to_vec();
    };
    let others: Vec<usize> = (0..seen.len()).filter(|&i| !seen[i]).collect();
    let queries: Vec<[f32; 3]> = others.iter().map(|&i| centroid(&mesh.faces[i])).collect();
    let d = tree.nearest_distances(&queries);
    let mut out = seen.to_vec();
    for (&i, d) in others.iter().zip(d) {
        out[i] = d <= margin;
    }
    out
}

/// Rule 4 of the module docs: the part of `mesh` that at least `min_views` of `cameras` see
/// ([`visibility_filter`]), grown by `margin` (mesh units, [`grow_by_distance`]), and the number
/// of faces removed. `min_views = 0`, or no cameras, returns the mesh unchanged.
pub fn cull_unseen(
    mesh: &TriMesh,
    cameras: &[&Camera],
    min_views: usize,
    margin: f64,
) -> (TriMesh, usize) {
    let cut = cull_unseen_parts(mesh, cameras, min_views, margin, 0.0);
    (cut.seen, cut.faces_unseen)
}

/// What rule 4 and its two follow-ups leave of a closed cleaned mesh ([`cull_unseen_parts`]).
#[derive(Clone, Debug)]
pub struct UnseenCut {
    /// The scored surface: the faces the cameras see, without the specks the cut leaves.
    pub seen: TriMesh,
    /// The closed surface without its components of which no face is seen.
    pub closed: TriMesh,
    /// Faces of the input that are not seen (rule 4's count; the two follow-ups remove more).
    pub faces_unseen: usize,
    /// Components of the closed surface of which no face is seen, and their faces.
    pub unseen_components_removed: usize,
    pub faces_in_unseen_components: usize,
    /// Components of the seen surface below the area share (rule 2 on the cut), and their faces.
    pub cut_specks_removed: usize,
    pub faces_in_cut_specks: usize,
}

/// Rule 4 with its two follow-ups, from per-face `seen` flags of a closed cleaned mesh:
/// - a component of the closed surface of which no face is seen goes from the closed surface
///   too (a floater behind the object, that rules 1–3 keep because it is large and outside
///   every other component: `relief` at seed 2, 2.9 % of the object's area, 38 mm behind it);
/// - rule 2 runs again on the seen surface with the same `min_area_share`: the cut leaves specks
///   where a few faces are seen among unseen ones (three of 0.2–0.5 mm² on that run).
pub fn split_unseen(mesh: &TriMesh, seen: &[bool], min_area_share: f64) -> UnseenCut {
    assert_eq!(seen.len(), mesh.faces.len(), "one flag per face");
    let (labels, n) = face_components(mesh);
    let mut any_seen = vec![false; n];
    for (&l, &s) in labels.iter().zip(seen) {
        any_seen[l as usize] |= s;
    }
    let keep_closed: Vec<bool> = labels.iter().map(|&l| any_seen[l as usize]).collect();
    let closed = keep_faces(mesh, &keep_closed);
    let cut = keep_faces(mesh, seen);
    let (keep_cut, _, specks) = small_component_filter(&cut, min_area_share);
    let seen_mesh = keep_faces(&cut, &keep_cut);
    UnseenCut {
        faces_unseen: mesh.faces.len() - cut.faces.len(),
        unseen_components_removed: any_seen.iter().filter(|s| !**s).count(),
        faces_in_unseen_components: mesh.faces.len() - closed.faces.len(),
        cut_specks_removed: specks,
        faces_in_cut_specks: cut.faces.len() - seen_mesh.faces.len(),
        seen: seen_mesh,
        closed,
    }
}

/// Rule 4's verdict per face: seen by at least `min_views` of `cameras`
/// ([`visibility_filter`]), grown by `margin` ([`grow_by_distance`]). All `true` when
/// `min_views = 0` or there are no cameras.
pub fn seen_faces(mesh: &TriMesh, cameras: &[&Camera], min_views: usize, margin: f64) -> Vec<bool> {
    if min_views == 0 || cameras.is_empty() {
        return vec![true; mesh.faces.len()];
    }
    grow_by_distance(mesh, &visibility_filter(mesh, cameras, min_views), margin)
}

/// [`split_unseen`] on [`seen_faces`] (as [`cull_unseen`]). `min_views = 0`, or no cameras,
/// returns the mesh unchanged twice.
pub fn cull_unseen_parts(
    mesh: &TriMesh,
    cameras: &[&Camera],
    min_views: usize,
    margin: f64,
    min_area_share: f64,
) -> UnseenCut {
    if min_views == 0 || cameras.is_empty() {
        return split_unseen(mesh, &vec![true; mesh.faces.len()], 0.0);
    }
    split_unseen(
        mesh,
        &seen_faces(mesh, cameras, min_views, margin),
        min_area_share,
    )
}

#[cfg(test)]
mod tests {
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
        let cut = split_unseen(&m, &seen, 0.02);
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
        assert_eq!(split_unseen(&m, &seen, 0.0).seen.faces.len(), n_seen_a + 1);
        let all = split_unseen(&m, &vec![true; m.faces.len()], 0.02);
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
        crate::sim::rig::look_at(
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
}
