//! Mesh clean-up after extraction: mask culling, removal of small floating components and of
//! components enclosed by another, and culling of what no camera sees.
//!
//! Four rules, applied in this order to the mesh in **normalised space** (cameras of the training
//! views):
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
//!    component's triangles; Jacobson, Kavan & Sorkine-Hornung, *Robust Inside-Outside Segmentation
//!    using Generalized Winding Numbers*, SIGGRAPH 2013) is removed. Such a shell is a cavity
//!    inside the object: no camera outside the object sees it, so no image supports it, and DTU's
//!    scans hold only visible surface. Such bubbles (inside a ring's tube, say) can hold a few
//!    percent of the surface, which the area rule keeps. A part that sits in another's hole (a ball
//!    inside a ring) has winding number 0 there and stays (tested). The winding number does not
//!    need the larger component to be closed (mask culling may have cut it) and does not depend on
//!    its face orientation.
//!
//! 4. **Unseen faces** ([`cull_unseen`], run by `reconstruct` after the three rules above when
//!    `mesh.clean_min_visible_views > 0`): a face is kept when at least that many training cameras
//!    see its centroid, in their image and not hidden by the mesh itself (one ray per camera
//!    through the mesh's own BVH). What no camera sees (the underside of an object on a turntable,
//!    the back of a plaque shot from the front) has no image evidence: the SDF there is whatever
//!    the initialisation left, and it costs accuracy where it pokes into the observed volume. The
//!    rule mirrors how the ground truth is made: DTU's structured-light scans, and the simulator's
//!    points (`sim::gt`), hold only surface that some camera sees. Two views, the default, is the
//!    least that triangulates a point; it is the default of NeuralWarp's triangle filter (Darmon et
//!    al., CVPR 2022, `evaluation/mesh_filtering.py`, `visible_mask` with `--min_nb_visible 2`),
//!    which rasterises the mesh in each view where this casts rays. The result is an open surface;
//!    `reconstruct` keeps the closed one beside it (`mesh_closed.ply`) and measures the genus on
//!    that. An optional margin ([`grow_by_distance`], `mesh.clean_visible_margin_mm`, default 0)
//!    keeps faces near a seen one as well: surface that the truth shows to a single camera at
//!    85–90° (a silhouette rim) is lost without it, but the unseen bulges it is meant to remove
//!    start right at the seen edges, so any margin keeps their worst part (measured:
//!    docs/recipe.md).
//!    Two follow-ups ([`split_unseen`]): a component of the closed surface of which no face is
//!    seen is removed from the closed surface as well (a floater behind the object, which rules
//!    1–3 keep when it is large and outside every other component), and rule 2 runs again on
//!    the seen surface, which the cut can leave with specks: by default on each piece the cut
//!    leaves; with [`SpeckRule::Part`] on each closed part's seen area, which keeps the pieces
//!    the cut separates from a part's main piece.
//!
//! Faces that lose a vertex are removed; vertices no face uses are dropped and the rest renumbered
//! in their original order, so the result is deterministic.

use super::topology::UnionFind;
use super::TriMesh;
use crate::scene::camera::{pixel_of, Camera};
use crate::scene::image::dilate_mask;
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
    let keep_comp = components_by_area(mesh, &labels, n, |_| true, min_area_share);
    let dropped = keep_comp.iter().filter(|k| !**k).count();
    (
        labels.iter().map(|&l| keep_comp[l as usize]).collect(),
        n,
        dropped,
    )
}

/// Per component (`labels`: one of `0..n` per face): whether the area of its faces that
/// `counted` admits (by face index) reaches `min_area_share` of the largest such area.
fn components_by_area(
    mesh: &TriMesh,
    labels: &[u32],
    n: usize,
    counted: impl Fn(usize) -> bool,
    min_area_share: f64,
) -> Vec<bool> {
    let mut area = vec![0.0f64; n];
    for (i, (f, &l)) in mesh.faces.iter().zip(labels).enumerate() {
        if counted(i) {
            area[l as usize] += face_area(mesh, f);
        }
    }
    let largest = area.iter().cloned().fold(0.0, f64::max);
    area.iter()
        .map(|&a| a >= min_area_share * largest)
        .collect()
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
    let tracer = super::trace::Tracer::new(&tris);
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
    let cut = cull_unseen_parts(mesh, cameras, min_views, margin, 0.0, SpeckRule::Piece);
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

/// How rule 4's second follow-up judges what the cut leaves (`mesh.clean_specks_by_part`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpeckRule {
    /// Each piece of the seen surface by its own area, against the largest piece's (rule 2 on
    /// the cut).
    #[default]
    Piece,
    /// Each part of the closed surface by the area of its seen faces, against the part with
    /// the most: every piece of a part that passes stays, however small. The cut splits one
    /// closed surface into pieces wherever a strip of it goes unseen (under a limb, inside a
    /// fold), and each piece is surface that two cameras see, while a floater is a part of its
    /// own whose seen share is small.
    Part,
}

/// Rule 4 with its two follow-ups, from per-face `seen` flags of a closed cleaned mesh:
/// - a component of the closed surface of which no face is seen goes from the closed surface
///   too (a floater behind the object, that rules 1–3 keep because it is large and outside
///   every other component);
/// - rule 2 runs again on what is seen with the same `min_area_share`: the cut leaves specks
///   where a few faces are seen among unseen ones. `specks` says what it compares
///   ([`SpeckRule`]).
pub fn split_unseen(
    mesh: &TriMesh,
    seen: &[bool],
    min_area_share: f64,
    specks: SpeckRule,
) -> UnseenCut {
    assert_eq!(seen.len(), mesh.faces.len(), "one flag per face");
    let (labels, n) = face_components(mesh);
    let mut any_seen = vec![false; n];
    for (&l, &s) in labels.iter().zip(seen) {
        any_seen[l as usize] |= s;
    }
    let keep_closed: Vec<bool> = labels.iter().map(|&l| any_seen[l as usize]).collect();
    let closed = keep_faces(mesh, &keep_closed);
    let cut = keep_faces(mesh, seen);
    let (seen_mesh, specks) = match specks {
        SpeckRule::Piece => {
            let (keep_cut, _, dropped) = small_component_filter(&cut, min_area_share);
            (keep_faces(&cut, &keep_cut), dropped)
        }
        SpeckRule::Part => {
            let keep_part = components_by_area(mesh, &labels, n, |i| seen[i], min_area_share);
            let keep: Vec<bool> = labels
                .iter()
                .zip(seen)
                .map(|(&l, &s)| s && keep_part[l as usize])
                .collect();
            let dropped = (0..n).filter(|&c| any_seen[c] && !keep_part[c]).count();
            (keep_faces(mesh, &keep), dropped)
        }
    };
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
    specks: SpeckRule,
) -> UnseenCut {
    if min_views == 0 || cameras.is_empty() {
        return split_unseen(mesh, &vec![true; mesh.faces.len()], 0.0, specks);
    }
    split_unseen(
        mesh,
        &seen_faces(mesh, cameras, min_views, margin),
        min_area_share,
        specks,
    )
}

#[cfg(test)]
mod tests;
