//! A prepared synthetic scene: the object placed in the rig and the world, the cameras, the
//! normalisation, the ground plane and the ray tracers, built once from a [`SceneDescription`].

use super::degrade::{self, Degradation};
use super::desc::{SceneDescription, PLANE_GAP_MM};
use super::rig::{self, Frame};
use super::shapes::{self, Mesh};
use super::texture::SolidTexture;
use super::SimError;
pub use crate::mesh::trace::Tracer;
use crate::scene::{Camera, Normalization};
use dtu_eval::gt::Plane;
use dtu_eval::TriMesh;
use glam::Vec3A;
use nalgebra::Vector3;
use obvhs::triangle::Triangle;

/// A scene ready to render and to sample ground truth from.
pub struct SimScene {
    /// The (validated) description.
    pub desc: SceneDescription,
    /// Rig ↔ world frames.
    pub frame: Frame,
    /// The object in world coordinates (mm, f32): the ground-truth surface.
    pub mesh_world: TriMesh,
    /// The object in the rig frame (f32, derived from `mesh_world`), one triangle per face.
    pub object_tris: Vec<Triangle>,
    /// True when the mesh is closed and consistently outward-oriented (every built-in shape),
    /// which lets the ground truth skip points whose triangle faces away from a camera.
    pub closed_oriented: bool,
    /// World-frame cameras (mm), in view order.
    pub cameras: Vec<Camera>,
    /// Camera distance from the object centre (mm).
    pub distance_mm: f64,
    /// `scale_mat`: world = `s`·normalised + `c`.
    pub normalization: Normalization,
    /// The ground plane in world coordinates (`Plane.mat`): `[x, y, z, 1]·P > 0` above it.
    pub plane: Plane,
    /// The plane's height in the rig frame (`z`, mm).
    pub plane_z_rig: f64,
    /// Occlusion tracer over the object alone (ground truth).
    pub object_tracer: Tracer,
    /// Tracer over the object and, when the ground plane effect is on, the plane's two
    /// triangles (indices `object_tris.len()..`).
    pub render_tracer: Option<Tracer>,
    /// Per face, the three corner normals (rig frame) for smooth shading; only computed when
    /// Lambert shading with `smooth_normals` is on.
    pub corner_normals: Option<Vec<[Vec3A; 3]>>,
    /// The object's procedural albedo, when the texture effect is on.
    pub texture: Option<SolidTexture>,
    /// The degradations of the `degrade` effect, in order.
    pub degradations: Vec<Degradation>,
}

fn v3a(p: [f64; 3]) -> Vec3A {
    Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32)
}

/// Per face corner, the area-weighted mean of the normals of the faces around that vertex that
/// turn less than `crease_deg` from this face (flat faces and sharp edges stay sharp).
pub fn crease_normals(
    tris: &[Triangle],
    faces: &[[u32; 3]],
    n_vertices: usize,
    crease_deg: f32,
) -> Vec<[Vec3A; 3]> {
    let area_normals: Vec<Vec3A> = tris
        .iter()
        .map(|t| (t.v1 - t.v0).cross(t.v2 - t.v0))
        .collect();
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); n_vertices];
    for (fi, f) in faces.iter().enumerate() {
        for &v in f {
            around[v as usize].push(fi as u32);
        }
    }
    let cos_crease = crease_deg.to_radians().cos();
    faces
        .iter()
        .enumerate()
        .map(|(fi, f)| {
            let own = area_normals[fi].normalize_or_zero();
            f.map(|v| {
                let mut sum = Vec3A::ZERO;
                for &g in &around[v as usize] {
                    let n = area_normals[g as usize];
                    if n.normalize_or_zero().dot(own) >= cos_crease {
                        sum += n;
                    }
                }
                let s = sum.normalize_or_zero();
                if s == Vec3A::ZERO {
                    own
                } else {
                    s
                }
            })
        })
        .collect()
}

impl SimScene {
    /// Builds the object, rig, normalisation, plane and tracers of a description.
    pub fn prepare(desc: &SceneDescription) -> Result<Self, SimError> {
        desc.validate()?;
        let o = &desc.object;
        let (raw, source): (Mesh, String) = match (&o.shape, &o.mesh) {
            (Some(shape), _) => (
                shapes::procedural(*shape),
                format!("shape '{}'", shape.name()),
            ),
            (None, Some(path)) => (
                shapes::load_mesh(path, o.up_axis)?,
                path.display().to_string(),
            ),
            (None, None) => unreachable!("validate() requires a shape or a mesh"),
        };
        let closed_oriented = raw.is_closed_oriented() && raw.signed_volume6() > 0.0;
        let bad_mesh = |problem: String| SimError::BadMesh {
            path: source.clone().into(),
            problem,
        };
        let (raw_area, n_faces) = (raw.area(), raw.faces.len());
        let stray = raw
            .farthest_from_median()
            .map(|(i, d)| (i, raw.vertices[i].map(|c| c as f32), d));
        // A mesh with no extent (every vertex one point) is named as such first.
        let local = raw.centre_and_scale(o.radius_mm).map_err(bad_mesh)?;
        if raw_area.is_nan() || raw_area <= 0.0 {
            return Err(bad_mesh(format!(
                "has zero surface area: all {n_faces} faces are degenerate (repeated or \
                 collinear corners), so there is nothing to render"
            )));
        }
        let frame = Frame::new(o.center_mm);
        // The world mesh (f32) is the ground truth; the rig-frame triangles are derived from it
        // so the renderer traces exactly that surface (up to f32 rounding, < 2e-5 mm).
        let mesh_world = TriMesh {
            vertices: local
                .vertices
                .iter()
                .map(|v| {
                    let w = frame.to_world(&Vector3::from(*v));
                    [w.x as f32, w.y as f32, w.z as f32]
                })
                .collect(),
            faces: local.faces.clone(),
        };
        let rig_vertices: Vec<Vec3A> = mesh_world
            .vertices
            .iter()
            .map(|w| {
                let r = frame.to_rig(&Vector3::new(w[0] as f64, w[1] as f64, w[2] as f64));
                v3a([r.x, r.y, r.z])
            })
            .collect();
        let object_tris: Vec<Triangle> = mesh_world
            .faces
            .iter()
            .map(|f| Triangle {
                v0: rig_vertices[f[0] as usize],
                v1: rig_vertices[f[1] as usize],
                v2: rig_vertices[f[2] as usize],
            })
            .collect();

        let [w, h] = desc.rig.resolution;
        let k = rig::intrinsics(w, h);
        let distance_mm = desc
            .rig
            .distance_mm
            .unwrap_or_else(|| rig::fit_distance(o.radius_mm, &k, w, h));
        // Scaled into the rig, the surface must cover a pixel at least: one vertex far from the
        // rest (a stray point, a unit slip) shrinks everything else to nothing.
        let pixel_mm = distance_mm / k[(0, 0)].max(k[(1, 1)]);
        let area_mm2 = local.area();
        if area_mm2.is_nan() || area_mm2 < pixel_mm * pixel_mm {
            let (i, at, d) = stray.unwrap_or_default();
            return Err(bad_mesh(format!(
                "scaled into the rig (its bounding radius set to {} mm), the surface totals \
                 {area_mm2:.3e} mm², less than one pixel ({:.3} mm² at the cameras' \
                 {distance_mm:.0} mm): nothing would be rendered. The vertex farthest from the \
                 others' median is vertex {i} at {at:?}, {d:.3e} file units from it: a stray \
                 vertex, or one in another unit?",
                o.radius_mm,
                pixel_mm * pixel_mm
            )));
        }
        let cameras = rig::cameras(&desc.rig, &frame, distance_mm);
        let normalization = rig::normalization(&mesh_world.vertices, desc.rig.scale_margin);

        let z_min = rig_vertices
            .iter()
            .map(|v| v.z as f64)
            .fold(f64::INFINITY, f64::min);
        let plane_z_rig = z_min - PLANE_GAP_MM;
        let up = frame.up_world();
        let on_plane = frame.to_world(&Vector3::new(0.0, 0.0, plane_z_rig));
        let plane = Plane([up.x, up.y, up.z, -up.dot(&on_plane)]);
        if let Some(cam) = cameras.iter().find(|c| plane.eval(c.center.into()) <= 0.0) {
            return Err(SimError::Invalid {
                key: "rig.elevation_deg".into(),
                problem: format!(
                    "puts a camera at {:?} below the ground plane; raise the lowest elevation",
                    cam.center.as_slice()
                ),
            });
        }

        let object_tracer = Tracer::new(&object_tris);
        let render_tracer = desc.effects.ground_plane().map(|gp| {
            let s = (gp.half_size * o.radius_mm) as f32;
            let z = plane_z_rig as f32;
            let c = [
                Vec3A::new(-s, -s, z),
                Vec3A::new(s, -s, z),
                Vec3A::new(s, s, z),
                Vec3A::new(-s, s, z),
            ];
            let mut all = object_tris.clone();
            all.push(Triangle {
                v0: c[0],
                v1: c[1],
                v2: c[2],
            });
            all.push(Triangle {
                v0: c[0],
                v1: c[2],
                v2: c[3],
            });
            Tracer::new(&all)
        });
        let corner_normals = desc
            .effects
            .lambert()
            .filter(|s| s.smooth_normals)
            .map(|_| {
                crease_normals(
                    &object_tris,
                    &mesh_world.faces,
                    mesh_world.vertices.len(),
                    30.0,
                )
            });
        let texture = desc.effects.texture().map(|t| SolidTexture {
            pattern: t.pattern,
            scale_mm: t.scale_mm,
            seed: desc.seed,
        });
        let degradations = degrade::parse_all(&desc.effects.degrade)?;
        Ok(Self {
            desc: desc.clone(),
            frame,
            mesh_world,
            object_tris,
            closed_oriented,
            cameras,
            distance_mm,
            normalization,
            plane,
            plane_z_rig,
            object_tracer,
            render_tracer,
            corner_normals,
            texture,
            degradations,
        })
    }

    /// A camera's centre in the rig frame.
    pub fn camera_center_rig(&self, view: usize) -> Vector3<f64> {
        self.frame.to_rig(&self.cameras[view].center)
    }
}
