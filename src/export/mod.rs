//! Meshes people can open: the trained colour network's colours on the mesh, a textured mesh, a
//! turntable, and the held-out views on one sheet.
//!
//! The field lives in the normalised space (`X_world = s·X_norm + c`, the scene's
//! [`Normalization`]); meshes are in world millimetres. Every query maps world points back to the
//! normalised space first. Colours are the colour network's at the surface point: normal `n` from
//! the SDF's central differences, appearance code 0 (the identity manipulation) and `p = 0`
//! under SIA and DIA (the paper's test-time query, the one the held-out renders use), and a
//! view direction chosen by `export.view_direction` ([`colors::ViewDirection`]: head-on `−n`,
//! or the training cameras' directions weighted towards head-on).
//!
//! What is written (file names are the same in a run folder and in `neus-aug export --out DIR`):
//! - `mesh.ply`: binary little-endian PLY, `float x y z` (world mm, the geometry's bytes as
//!   before), `float nx ny nz` (unit SDF normals, world frame), `uchar red green blue` ([`ply`]).
//! - `mesh_textured.obj` + `.mtl` + `.png`: the mesh with an unwrapped atlas ([`unwrap`]) and a
//!   texture baked from the field ([`bake`]); `vt` with `v` up ([`obj`]).
//! - `mesh_textured.glb`: binary glTF 2.0, the same mesh and texture (PNG embedded), `v` down,
//!   metres and +Y up through the node's matrix ([`glb`]).
//! - `renders/turntable.gif`: the coloured mesh turning, colour beside normals ([`turntable`]);
//!   `renders/heldout_sheet.png`: each held-out view's truth, render and normals in a row.
//!
//! Layering: uses `scene`, `field`, `render`, `train` (metrics and camera rays) and `mesh`'s
//! `dtu_eval` types; `reconstruct` and the `export` command call it, nothing below does.
//!
//! Every file is written atomically ([`dtu_eval::atomic`]): a failure leaves no half-written
//! file under its name.

pub mod bake;
pub mod check;
pub mod colors;
pub mod glb;
pub mod obj;
pub mod ply;
pub mod raycast;
pub mod turntable;
pub mod unwrap;

use crate::render::model::{ModelError, NeusModel};
use crate::render::Schedule;
use crate::scene::{Camera, ImageError, Normalization, Scene};
use dtu_eval::mesh::TriMesh;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use bake::{bake_texture, BakedTexture};
pub use colors::{SurfaceField, SurfaceShading, ViewDirection};
pub use unwrap::{unwrap_mesh, UvMesh, UvStats};

/// Largest accepted texture side (texels): 16384² RGB is 768 MiB before encoding.
pub const MAX_TEXTURE_SIZE: u32 = 16384;
/// Smallest accepted texture side (texels): below it the charts' padding leaves no room.
pub const MIN_TEXTURE_SIZE: u32 = 16;

/// File names of the exported meshes inside a folder.
pub const MESH_PLY: &str = "mesh.ply";
pub const TEXTURED_OBJ: &str = "mesh_textured.obj";
pub const TEXTURED_MTL: &str = "mesh_textured.mtl";
pub const TEXTURED_PNG: &str = "mesh_textured.png";
pub const TEXTURED_GLB: &str = "mesh_textured.glb";
pub const TURNTABLE_GIF: &str = "turntable.gif";
pub const HELDOUT_SHEET: &str = "heldout_sheet.png";

/// What `reconstruct` exports besides the scored mesh (`[export]` in `config.toml`; absent from
/// a config's text while every key has its default, so earlier run folders read the same).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExportConfig {
    /// Vertex normals and colours in `mesh.ply` (`x y z nx ny nz red green blue`). `false`
    /// writes positions and faces only: the bytes `mesh.ply` had before this key. The positions
    /// and faces are the same either way.
    pub colors: bool,
    /// Also write the textured mesh (`mesh_textured.obj/.mtl/.png` and `mesh_textured.glb`);
    /// `reconstruct --export textured`. Off by default: the unwrap and the bake cost seconds to
    /// tens of seconds on a `default`-size mesh.
    pub textured: bool,
    /// Side of the square texture in texels, `16..=16384`.
    pub texture_size: u32,
    /// Frames of `renders/turntable.gif` (one turn); `0` writes none.
    pub turntable_frames: u32,
    /// Width and height of one panel of the turntable in pixels (two panels side by side).
    pub turntable_size: [u32; 2],
    /// Write `renders/heldout_sheet.png` (held-out views: truth, render, normals).
    pub heldout_sheet: bool,
    /// The view direction of the colour query: `cameras` (the training cameras' directions,
    /// weighted towards head-on) or `head_on` (`−n`); see [`ViewDirection`].
    pub view_direction: ViewDirection,
}

impl Default for ExportConfig {
    fn default() -> Self {
        Self {
            colors: true,
            textured: false,
            texture_size: 1024,
            turntable_frames: 30,
            turntable_size: [160, 120],
            heldout_sheet: true,
            view_direction: ViewDirection::default(),
        }
    }
}

impl ExportConfig {
    /// Whether every key has its default (the section is then left out of `config.toml`).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The first out-of-range key: `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, String)> {
        if let Err(why) = check_texture_size(self.texture_size) {
            return Some(("export.texture_size", self.texture_size.to_string(), why));
        }
        if self.turntable_frames > 360 {
            return Some((
                "export.turntable_frames",
                self.turntable_frames.to_string(),
                "must be in 0..=360".into(),
            ));
        }
        let [w, h] = self.turntable_size;
        if !(8..=1024).contains(&w) || !(8..=1024).contains(&h) {
            return Some((
                "export.turntable_size",
                format!("[{w}, {h}]"),
                "each side must be in 8..=1024 pixels".into(),
            ));
        }
        None
    }
}

/// Checks a texture side (texels): `16..=16384`.
pub fn check_texture_size(n: u32) -> Result<(), String> {
    if (MIN_TEXTURE_SIZE..=MAX_TEXTURE_SIZE).contains(&n) {
        Ok(())
    } else {
        Err(format!(
            "must be in {MIN_TEXTURE_SIZE}..={MAX_TEXTURE_SIZE} texels per side (got {n}; 16384² \
             RGB takes 768 MiB)"
        ))
    }
}

/// Why an export failed; each variant names the file or the option at fault.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A mesh with no faces cannot be coloured, unwrapped or rendered.
    #[error("{path}: the mesh is empty ({vertices} vertices, no faces): nothing to export")]
    EmptyMesh { path: PathBuf, vertices: usize },
    /// An option outside its range.
    #[error("{option} = {value} is invalid: {why}")]
    Option {
        option: &'static str,
        value: String,
        why: String,
    },
    /// The unwrapper refused the mesh.
    #[error("UV unwrapping of {what} failed: {why}")]
    Unwrap { what: String, why: String },
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Ply(#[from] dtu_eval::ply::PlyError),
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> ExportError + '_ {
    move |source| ExportError::Io {
        path: path.into(),
        source,
    }
}

/// World mm → normalised space: `(X − c)/s`, in f64 then rounded to f32.
pub fn to_normalized(points: &[[f32; 3]], norm: &Normalization) -> Vec<[f32; 3]> {
    let (s, c) = (norm.scale, norm.center);
    points
        .iter()
        .map(|p| [0, 1, 2].map(|a| ((p[a] as f64 - c[a]) / s) as f32))
        .collect()
}

/// A mesh in world mm with unit vertex normals (world frame) and 8-bit colours, one per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColoredMesh {
    /// Positions and faces, unchanged from the mesh given.
    pub mesh: TriMesh,
    /// `[n_vertices][3]` unit normals (SDF gradient; world frame = normalised frame's directions).
    pub normals: Vec<[f32; 3]>,
    /// `[n_vertices][3]` colours, sRGB as the training images are, 0–255.
    pub colors: Vec<[u8; 3]>,
    /// Vertices whose query was not finite and got the fallback ([`SurfaceShading`]).
    pub fallbacks: usize,
}

/// Colours and normals of `mesh` (world mm) from the field ([`SurfaceField::shade`] at its
/// vertices). An empty mesh (no faces) is [`ExportError::EmptyMesh`] naming `what`.
pub fn color_mesh(
    field: &SurfaceField,
    mesh: &TriMesh,
    norm: &Normalization,
    what: &Path,
) -> Result<ColoredMesh, ExportError> {
    if mesh.faces.is_empty() {
        return Err(ExportError::EmptyMesh {
            path: what.into(),
            vertices: mesh.vertices.len(),
        });
    }
    let pts = to_normalized(&mesh.vertices, norm);
    let fallback = colors::area_weighted_normals(mesh);
    let s = field.shade(&pts, &fallback);
    Ok(ColoredMesh {
        mesh: mesh.clone(),
        normals: s.normal,
        colors: s.rgb.iter().map(|c| c.map(to_u8)).collect(),
        fallbacks: s.fallbacks,
    })
}

/// `[0, 1]` → 0–255, rounded to nearest (NaN → 0; callers have replaced NaN already).
#[inline]
pub fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The textured mesh in memory: the unwrapped mesh and its baked texture.
#[derive(Clone, Debug)]
pub struct TexturedMesh {
    pub uv: UvMesh,
    pub texture: BakedTexture,
}

/// Unwraps `colored.mesh` and bakes a `size × size` texture from the field.
pub fn texture_mesh(
    field: &SurfaceField,
    colored: &ColoredMesh,
    norm: &Normalization,
    size: u32,
) -> Result<TexturedMesh, ExportError> {
    check_texture_size(size).map_err(|why| ExportError::Option {
        option: "texture size",
        value: size.to_string(),
        why,
    })?;
    let uv = unwrap_mesh(&colored.mesh, &colored.normals, size)?;
    let texture = bake_texture(field, &uv, norm, size);
    Ok(TexturedMesh { uv, texture })
}

/// Writes `mesh_textured.obj/.mtl/.png` and `mesh_textured.glb` into `dir` (each atomically; the
/// PNG first, so an OBJ never names a missing texture). `up`: the scene's up direction (world),
/// recorded in the glTF node's rotation.
pub fn write_textured(
    dir: &Path,
    t: &TexturedMesh,
    formats: &Formats,
    up: [f64; 3],
    center_mm: [f64; 3],
) -> Result<(), ExportError> {
    let png = t.texture.png_bytes()?;
    if formats.obj {
        let p = dir.join(TEXTURED_PNG);
        dtu_eval::atomic::write_atomic(&p, &png).map_err(io_err(&p))?;
        obj::write_obj(dir, TEXTURED_OBJ, TEXTURED_MTL, TEXTURED_PNG, &t.uv)?;
    }
    if formats.glb {
        let p = dir.join(TEXTURED_GLB);
        let bytes = glb::glb_bytes(&t.uv, &png, &glb::node_matrix(up, center_mm));
        dtu_eval::atomic::write_atomic(&p, &bytes).map_err(io_err(&p))?;
    }
    Ok(())
}

/// Which files an export writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Formats {
    pub ply: bool,
    pub obj: bool,
    pub glb: bool,
}

/// The scene's up direction (world frame, unit): the mean of the cameras' image-up axes
/// (`−y` of the OpenCV camera frame, `−Rᵀ·e_y`). DTU-style rigs look at the object from a cap
/// above it, so this is the direction a viewer expects on top. `+z` without cameras.
pub fn scene_up(cameras: &[Camera]) -> [f64; 3] {
    let mut u = [0.0f64; 3];
    for c in cameras {
        let r = c.r.transpose();
        for (a, v) in u.iter_mut().enumerate() {
            *v -= r[(a, 1)];
        }
    }
    let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    if n > 1e-9 && n.is_finite() {
        u.map(|v| v / n)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// What [`export_run_outputs`] did, for the run's log.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RunExportSummary {
    /// Seconds of the whole step.
    pub seconds: f64,
    /// Vertices whose colour or normal query fell back (non-finite).
    pub color_fallbacks: usize,
    /// Texels whose query fell back (textured export only).
    pub texel_fallbacks: usize,
    /// What was written (file names, relative to the run folder).
    pub written: Vec<String>,
}

/// Inputs of [`export_run_outputs`]: what `reconstruct` has in hand after its held-out renders.
pub struct RunExport<'a> {
    pub cfg: &'a ExportConfig,
    /// The colour query on the trained parameters.
    pub field: &'a SurfaceField<'a>,
    /// The scored mesh (world mm), as written to `mesh.ply` by the geometry writer.
    pub mesh: &'a TriMesh,
    pub normalization: &'a Normalization,
    /// Every view's camera (normalised space): the turntable's orbit and up direction.
    pub cameras: &'a [Camera],
    /// The held-out views rendered into `renders/` (`view{v:03}_{gt,rgb,normal}.png`).
    pub heldout: &'a [usize],
    /// Render background (what a ray that misses the mesh shows).
    pub background: [f32; 3],
    /// The run folder.
    pub out: &'a Path,
}

/// `reconstruct`'s export step: `mesh.ply` rewritten with normals and colours (same positions and
/// faces), the textured mesh when asked, `renders/turntable.gif` and `renders/heldout_sheet.png`.
/// An empty mesh keeps the geometry-only `mesh.ply` and skips what needs a surface.
pub fn export_run_outputs(r: &RunExport) -> Result<RunExportSummary, ExportError> {
    let t0 = Instant::now();
    let mut sum = RunExportSummary::default();
    let renders = r.out.join("renders");
    let mesh_path = r.out.join(MESH_PLY);
    let has_surface = !r.mesh.faces.is_empty();
    let want_colors = has_surface && (r.cfg.colors || r.cfg.textured || r.cfg.turntable_frames > 0);
    let colored = if want_colors {
        Some(color_mesh(r.field, r.mesh, r.normalization, &mesh_path)?)
    } else {
        None
    };
    if let (Some(c), true) = (&colored, r.cfg.colors) {
        ply::write_colored_ply(&mesh_path, c)?;
        sum.color_fallbacks = c.fallbacks;
        sum.written.push(MESH_PLY.into());
    }
    let stale = [TEXTURED_OBJ, TEXTURED_MTL, TEXTURED_PNG, TEXTURED_GLB];
    match &colored {
        Some(c) if r.cfg.textured => {
            let t = texture_mesh(r.field, c, r.normalization, r.cfg.texture_size)?;
            sum.texel_fallbacks = t.texture.fallbacks;
            let formats = Formats {
                ply: false,
                obj: true,
                glb: true,
            };
            write_textured(
                r.out,
                &t,
                &formats,
                scene_up(r.cameras),
                r.normalization.center,
            )?;
            sum.written.extend(stale.iter().map(|s| s.to_string()));
        }
        _ => {
            // A textured mesh left by an earlier run in this folder would not match this one.
            for f in stale {
                let p = r.out.join(f);
                if p.is_file() {
                    std::fs::remove_file(&p).map_err(io_err(&p))?;
                }
            }
        }
    }
    if let (Some(c), true) = (&colored, r.cfg.turntable_frames > 0) {
        std::fs::create_dir_all(&renders).map_err(io_err(&renders))?;
        let world: Vec<Camera> = r
            .cameras
            .iter()
            .map(|cam| {
                let n = r.normalization;
                cam.denormalized(n.scale, &n.center.into())
            })
            .collect();
        let orbit = turntable::Orbit::around(&world, &c.mesh, r.normalization.center);
        let scene = raycast::MeshScene::vertex_colored(c);
        let p = renders.join(TURNTABLE_GIF);
        turntable::write_turntable(
            &p,
            &scene,
            &orbit,
            r.cfg.turntable_frames,
            r.cfg.turntable_size,
            r.background,
        )?;
        sum.written.push(format!("renders/{TURNTABLE_GIF}"));
    }
    if r.cfg.heldout_sheet && !r.heldout.is_empty() {
        let p = renders.join(HELDOUT_SHEET);
        turntable::write_heldout_sheet(&p, &renders, r.heldout)?;
        sum.written.push(format!("renders/{HELDOUT_SHEET}"));
    }
    sum.seconds = t0.elapsed().as_secs_f64();
    Ok(sum)
}

/// The centres (normalised space) of the views `views` of `scene`.
pub fn camera_centres(scene: &Scene, views: &[usize]) -> Vec<[f32; 3]> {
    views
        .iter()
        .map(|&i| {
            let c = &scene.views[i].camera.center;
            [c.x as f32, c.y as f32, c.z as f32]
        })
        .collect()
}

/// `reconstruct`'s export step in one call: the colour query on the trained `params` under
/// `sched` (view directions from the training views `train_views`), then [`export_run_outputs`] with every view's camera for the turntable. Says what it
/// wrote (and any fallbacks) unless `quiet`.
#[allow(clippy::too_many_arguments)]
pub fn after_reconstruct(
    cfg: &ExportConfig,
    model: &NeusModel,
    params: &[f32],
    sched: Schedule,
    scene: &Scene,
    train_views: &[usize],
    mesh: &TriMesh,
    heldout: &[usize],
    out: &Path,
    quiet: bool,
) -> Result<RunExportSummary, ExportError> {
    let centres = camera_centres(scene, train_views);
    let field = SurfaceField::new(model, params, sched)?.with_view(cfg.view_direction, &centres);
    let cameras: Vec<Camera> = scene.views.iter().map(|v| v.camera.clone()).collect();
    let s = export_run_outputs(&RunExport {
        cfg,
        field: &field,
        mesh,
        normalization: &scene.normalization,
        cameras: &cameras,
        heldout,
        background: model.config.render.background,
        out,
    })?;
    let fb = s.color_fallbacks + s.texel_fallbacks;
    if fb > 0 {
        eprintln!(
            "warning: export: {} vertices and {} texels had a non-finite colour or normal query \
             and took the fallback (mid-grey, the mesh's own normal)",
            s.color_fallbacks, s.texel_fallbacks
        );
    }
    if !quiet && !s.written.is_empty() {
        eprintln!("export: {} in {:.2} s", s.written.join(", "), s.seconds);
    }
    Ok(s)
}
