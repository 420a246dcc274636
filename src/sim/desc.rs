//! The scene description: what to render and which effects to simulate, as a TOML file.
//!
//! Every table rejects unknown keys (`deny_unknown_fields`), so a misspelt effect such as
//! `shadow = {}` is an error naming the key and the accepted ones, not a silently ignored line.
//! Every effect is optional; an effect that is absent, or present with `enabled = false` (for
//! `degrade`: an empty list), is not computed at all and changes no pixel (see
//! [`super::render`] for the counters that prove it).
//!
//! Frames: light directions are given in the **rig frame** ([`super::rig`]): origin at the
//! object's bounding-box centre, `+z` up (away from the ground plane), cameras on the `−y` side.
//! Lengths are millimetres.
//!
//! ```toml
//! name = "blob"
//! scan = 101
//! seed = 0
//! [object]
//! shape = "blob"            # or: mesh = "bunny.ply" (+ up_axis = "+y")
//! radius_mm = 100.0
//! [rig]
//! views = 49
//! resolution = [400, 300]
//! [render]
//! spp = 4
//! [gt]
//! spacing_mm = 0.2
//! [effects]
//! shading = { model = "lambert", ambient = 0.35 }
//! texture = { pattern = "multiscale", scale_mm = 22.0 }
//! ```

use super::SimError;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A complete scene description: object, camera rig, sampling, ground truth and effects.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneDescription {
    /// Scene name (the built-in catalog's key; free text for custom scenes).
    pub name: String,
    /// DTU scan number used in the ground-truth file names (`stl{scan:03}_total.ply`, ...).
    /// Built-ins use 101–106; custom scenes default to 100.
    pub scan: u32,
    /// Seed of every random choice (texture noise, per-view exposure and light jitter,
    /// degradations). Same description and seed, same bytes.
    pub seed: u64,
    /// One line describing the scene (shown by `neus-aug synth --list`).
    pub summary: String,
    /// The object.
    pub object: ObjectSpec,
    /// The camera rig.
    pub rig: RigSpec,
    /// Pixel sampling and background.
    pub render: RenderSpec,
    /// Ground-truth generation.
    pub gt: GtSpec,
    /// The effects to simulate; absent ones cost nothing.
    pub effects: Effects,
}

impl Default for SceneDescription {
    fn default() -> Self {
        Self {
            name: "custom".into(),
            scan: 100,
            seed: 0,
            summary: String::new(),
            object: ObjectSpec::default(),
            rig: RigSpec::default(),
            render: RenderSpec::default(),
            gt: GtSpec::default(),
            effects: Effects::default(),
        }
    }
}

/// A procedural shape of the built-in catalog (see [`super::shapes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shape {
    /// Smooth genus-0 blob (a radially deformed icosphere).
    Blob,
    /// A leaning torus (genus 1; the cameras see through the hole).
    Torus,
    /// A body with rods and a fin about 1.5 % of the object's size thick.
    Thin,
    /// Boxes, a pyramid and a prism: planar faces and sharp edges.
    Blocks,
    /// A deep cup (a thick-walled surface of revolution).
    Cup,
    /// A leaning plaque whose face carries fine relief (ripples, domes, grooves).
    Relief,
    /// Genus 2: two fused tori (a figure of eight), leaning so the cameras see through both holes.
    #[serde(rename = "double-torus")]
    DoubleTorus,
    /// A thin sheet: a bent plate 3 mm thick (about 2 % of its size).
    Plate,
    /// Thin rods: a cube frame of 4 mm rods (genus 5).
    Rods,
}

impl Shape {
    /// All shapes, in catalog order.
    pub const ALL: [Shape; 9] = [
        Shape::Blob,
        Shape::Torus,
        Shape::Thin,
        Shape::Blocks,
        Shape::Cup,
        Shape::Relief,
        Shape::DoubleTorus,
        Shape::Plate,
        Shape::Rods,
    ];

    /// The lowercase name used in TOML.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Blob => "blob",
            Shape::Torus => "torus",
            Shape::Thin => "thin",
            Shape::Blocks => "blocks",
            Shape::Cup => "cup",
            Shape::Relief => "relief",
            Shape::DoubleTorus => "double-torus",
            Shape::Plate => "plate",
            Shape::Rods => "rods",
        }
    }
}

/// Which axis of a mesh file points up (towards the cameras' elevation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum UpAxis {
    #[serde(rename = "+x")]
    PosX,
    #[serde(rename = "-x")]
    NegX,
    #[serde(rename = "+y")]
    PosY,
    #[serde(rename = "-y")]
    NegY,
    #[serde(rename = "+z")]
    PosZ,
    #[serde(rename = "-z")]
    NegZ,
}

/// The object: a built-in shape or a mesh file, scaled into the rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectSpec {
    /// A built-in procedural shape (exactly one of `shape` and `mesh`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<Shape>,
    /// A triangle mesh file (`.ply` or `.obj`); relative paths are relative to the TOML file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// The mesh file's up axis (ignored for built-in shapes, which are made `+z` up).
    pub up_axis: UpAxis,
    /// The object is centred on its bounding-box centre and scaled so that its bounding sphere
    /// about that centre has this radius (mm). DTU objects are about 150–250 mm across.
    pub radius_mm: f64,
    /// World position (mm) of the object's bounding-box centre. Off the origin, as in DTU, so
    /// the normalisation is non-trivial; keep |coordinates| + radius below 512 mm so f32 world
    /// coordinates keep 3e-5 mm resolution.
    pub center_mm: [f64; 3],
    /// Constant albedo used when the `texture` effect is absent.
    pub albedo: [f32; 3],
}

impl Default for ObjectSpec {
    fn default() -> Self {
        Self {
            shape: None,
            mesh: None,
            up_axis: UpAxis::PosZ,
            radius_mm: 100.0,
            center_mm: [-18.0, 42.5, 395.0],
            albedo: [0.7, 0.7, 0.7],
        }
    }
}

/// The camera rig: a DTU-like spherical cap of views (see [`super::rig`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RigSpec {
    /// Number of views (DTU: 49).
    pub views: usize,
    /// Image size `[width, height]` in pixels; DTU's 1600×1200 intrinsics are scaled to it.
    pub resolution: [u32; 2],
    /// Camera distance from the object centre (mm); default: the smallest distance at which the
    /// bounding sphere fits every image with an 8 % margin (about 550 mm for a 100 mm radius).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance_mm: Option<f64>,
    /// Azimuth range (degrees) around the front (`−y`) direction.
    pub azimuth_deg: [f64; 2],
    /// Elevation range (degrees) above the horizontal plane through the object centre.
    pub elevation_deg: [f64; 2],
    /// `scale_mat`'s radius is the bounding-sphere radius times this margin.
    pub scale_margin: f64,
}

impl Default for RigSpec {
    fn default() -> Self {
        Self {
            views: 49,
            resolution: [400, 300],
            distance_mm: None,
            azimuth_deg: [-45.0, 45.0],
            elevation_deg: [20.0, 60.0],
            scale_margin: 1.1,
        }
    }
}

/// Pixel sampling.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderSpec {
    /// Samples per pixel, on a fixed pattern ([`super::render::sample_offsets`]); 1 = the pixel
    /// centre only.
    pub spp: u32,
    /// Colour of pixels that hit nothing (DTU's masked-out regions are black).
    pub background: [f32; 3],
}

impl Default for RenderSpec {
    fn default() -> Self {
        Self {
            spp: 4,
            background: [0.0, 0.0, 0.0],
        }
    }
}

/// Ground-truth generation (see [`super::gt`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GtSpec {
    /// Surface sampling spacing (mm), DTU's `MeshSupSamp` rule; DTU's evaluation uses 0.2 mm.
    pub spacing_mm: f64,
    /// `Res` of the observation mask: voxel edge (mm).
    pub obs_res_mm: f64,
    /// The observation mask considers voxels within this distance (mm) of a visible
    /// ground-truth point (20 mm, DTU's outlier cut-off, makes it the whole observed volume).
    pub obs_dilate_mm: f64,
    /// A point is occluded from a camera only by a surface more than this far (mm) in front of
    /// it along the line of sight.
    pub occlusion_eps_mm: f64,
}

impl Default for GtSpec {
    fn default() -> Self {
        Self {
            spacing_mm: 0.2,
            obs_res_mm: 2.0,
            obs_dilate_mm: 20.0,
            occlusion_eps_mm: 0.02,
        }
    }
}

fn yes() -> bool {
    true
}

/// The effects a scene calls for. `None` (absent) and `enabled = false` are the same: nothing of
/// that effect is computed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Effects {
    /// Shading model; absent = unlit albedo.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shading: Option<Shading>,
    /// Blinn-Phong highlights (needs `shading.model = "lambert"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub specular: Option<Specular>,
    /// Shadow rays towards the light (needs `shading.model = "lambert"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shadows: Option<Shadows>,
    /// Procedural albedo; absent = `object.albedo` everywhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture: Option<Texture>,
    /// Per-view exposure gain (seeded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exposure: Option<Exposure>,
    /// Per-view light direction changes (seeded; needs `shading.model = "lambert"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light_jitter: Option<LightJitter>,
    /// A ground plane under the object: in the images, never in the masks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ground_plane: Option<GroundPlane>,
    /// Image degradations `KIND:q` (the paper's appendix), applied in order after exposure.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub degrade: Vec<String>,
}

/// The shading model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShadingModel {
    /// Unlit: the pixel is the albedo (the same as no `shading` effect).
    Albedo,
    /// Lambertian with one directional light and an ambient term.
    Lambert,
}

/// `colour = albedo · (ambient + diffuse · max(0, n·l) · visibility)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Shading {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Shading model.
    pub model: ShadingModel,
    /// Direction towards the light, rig frame (normalised on use).
    pub direction: [f64; 3],
    /// Ambient term.
    pub ambient: f32,
    /// Directional light intensity.
    pub diffuse: f32,
    /// Interpolate normals across triangles whose normals differ by less than 30°
    /// (flat faces and sharp edges stay sharp).
    pub smooth_normals: bool,
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            enabled: true,
            model: ShadingModel::Lambert,
            direction: [-0.4, -0.5, 0.77],
            ambient: 0.3,
            diffuse: 0.75,
            smooth_normals: true,
        }
    }
}

/// Blinn-Phong: `+ strength · max(0, n·h)^exponent` (white), where the light reaches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Specular {
    #[serde(default = "yes")]
    pub enabled: bool,
    pub strength: f32,
    pub exponent: f32,
}

impl Default for Specular {
    fn default() -> Self {
        Self {
            enabled: true,
            strength: 0.35,
            exponent: 40.0,
        }
    }
}

/// Shadow rays towards the (directional) light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Shadows {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Shadow rays start this far (mm) off the surface along its normal, so a surface does not
    /// shadow itself through f32 rounding (the object's coordinates are < 200 mm, whose f32
    /// resolution is 1.5e-5 mm).
    pub offset_mm: f32,
}

impl Default for Shadows {
    fn default() -> Self {
        Self {
            enabled: true,
            offset_mm: 0.01,
        }
    }
}

/// Procedural solid textures, evaluated at the surface point in the rig frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pattern {
    /// Colour regions, spots and fine grain at three scales (the default: rich photometric cues).
    Multiscale,
    /// A 3-D checkerboard of two colours.
    Checker,
    /// Grey fractal value noise.
    Noise,
}

/// Procedural albedo.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Texture {
    #[serde(default = "yes")]
    pub enabled: bool,
    pub pattern: Pattern,
    /// The pattern's middle scale (mm); the multiscale pattern also uses ×3.5 and ×0.25.
    pub scale_mm: f32,
}

impl Default for Texture {
    fn default() -> Self {
        Self {
            enabled: true,
            pattern: Pattern::Multiscale,
            scale_mm: 16.0,
        }
    }
}

/// Per-view exposure: the image is multiplied by `exp(sigma · z)`, `z ~ N(0, 1)` per view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Exposure {
    #[serde(default = "yes")]
    pub enabled: bool,
    pub sigma: f32,
}

impl Default for Exposure {
    fn default() -> Self {
        Self {
            enabled: true,
            sigma: 0.15,
        }
    }
}

/// Per-view light direction: the light is turned by an angle uniform in `[0, degrees]` about a
/// random axis perpendicular to it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightJitter {
    #[serde(default = "yes")]
    pub enabled: bool,
    pub degrees: f64,
}

impl Default for LightJitter {
    fn default() -> Self {
        Self {
            enabled: true,
            degrees: 20.0,
        }
    }
}

/// A square ground plane below the object's lowest point, with a grey checker of its own.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundPlane {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Half the side of the square, as a multiple of `object.radius_mm`.
    pub half_size: f64,
    /// Checker cell (mm).
    pub checker_mm: f32,
    /// The two checker colours.
    pub colors: [[f32; 3]; 2],
}

impl Default for GroundPlane {
    fn default() -> Self {
        Self {
            enabled: true,
            half_size: 4.0,
            checker_mm: 25.0,
            colors: [[0.55, 0.52, 0.48], [0.35, 0.33, 0.31]],
        }
    }
}

/// The ground plane (`Plane.mat`, and the `ground_plane` effect's plane) lies this far (mm)
/// below the object's lowest point.
pub const PLANE_GAP_MM: f64 = 1.0;

impl Effects {
    /// The shading in force: `Some` only for an enabled Lambert model.
    pub fn lambert(&self) -> Option<&Shading> {
        self.shading
            .as_ref()
            .filter(|s| s.enabled && s.model == ShadingModel::Lambert)
    }
    /// The enabled specular effect.
    pub fn specular(&self) -> Option<&Specular> {
        self.specular.as_ref().filter(|s| s.enabled)
    }
    /// The enabled shadows effect.
    pub fn shadows(&self) -> Option<&Shadows> {
        self.shadows.as_ref().filter(|s| s.enabled)
    }
    /// The enabled texture effect.
    pub fn texture(&self) -> Option<&Texture> {
        self.texture.as_ref().filter(|s| s.enabled)
    }
    /// The enabled exposure effect.
    pub fn exposure(&self) -> Option<&Exposure> {
        self.exposure.as_ref().filter(|s| s.enabled)
    }
    /// The enabled light-jitter effect.
    pub fn light_jitter(&self) -> Option<&LightJitter> {
        self.light_jitter.as_ref().filter(|s| s.enabled)
    }
    /// The enabled ground plane.
    pub fn ground_plane(&self) -> Option<&GroundPlane> {
        self.ground_plane.as_ref().filter(|s| s.enabled)
    }
}

fn invalid(key: &str, problem: impl Into<String>) -> SimError {
    SimError::Invalid {
        key: key.into(),
        problem: problem.into(),
    }
}

fn positive(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(key, format!("is {v}, must be a positive number")))
    }
}

fn unit_range(key: &str, v: f32) -> Result<(), SimError> {
    if v.is_finite() && (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(invalid(key, format!("is {v}, must lie in [0, 1]")))
    }
}

fn colour(key: &str, c: [f32; 3]) -> Result<(), SimError> {
    c.iter().try_for_each(|&v| unit_range(key, v))
}

impl SceneDescription {
    /// Parses a description from TOML text; `source` names the text in errors (a file path or
    /// `"<builtin>"`). Relative mesh paths are resolved against `base_dir` when given.
    pub fn from_toml_str(
        text: &str,
        source: &str,
        base_dir: Option<&Path>,
    ) -> Result<Self, SimError> {
        let mut desc: Self = toml::from_str(text).map_err(|e| SimError::Toml {
            source_name: source.into(),
            message: e.to_string(),
        })?;
        if let (Some(base), Some(mesh)) = (base_dir, desc.object.mesh.as_mut()) {
            if mesh.is_relative() {
                *mesh = base.join(&*mesh);
            }
        }
        desc.validate()?;
        Ok(desc)
    }

    /// Reads and validates a TOML file.
    pub fn load(path: &Path) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path).map_err(|source| SimError::Io {
            path: path.into(),
            source,
        })?;
        Self::from_toml_str(&text, &path.display().to_string(), path.parent())
    }

    /// The description as TOML (what `scene.toml` holds; parsing it gives `self` back).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene description always serialises")
    }

    /// Checks every value; the error names the key at fault.
    pub fn validate(&self) -> Result<(), SimError> {
        let o = &self.object;
        match (&o.shape, &o.mesh) {
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "object",
                    "gives both 'shape' and 'mesh'; choose one",
                ))
            }
            (None, None) => {
                return Err(invalid(
                    "object",
                    "needs 'shape' (a built-in shape) or 'mesh' (a .ply/.obj file)",
                ))
            }
            _ => {}
        }
        positive("object.radius_mm", o.radius_mm)?;
        if o.center_mm.iter().any(|v| !v.is_finite()) {
            return Err(invalid("object.center_mm", "has a non-finite coordinate"));
        }
        colour("object.albedo", o.albedo)?;

        let r = &self.rig;
        if r.views == 0 {
            return Err(invalid("rig.views", "is 0: at least one view is needed"));
        }
        let [w, h] = r.resolution;
        if w == 0 || h == 0 {
            return Err(invalid(
                "rig.resolution",
                format!("is {w}x{h}: width and height must be at least 1"),
            ));
        }
        if w > 16384 || h > 16384 {
            return Err(invalid(
                "rig.resolution",
                format!("is {w}x{h}: at most 16384 per side"),
            ));
        }
        if let Some(d) = r.distance_mm {
            positive("rig.distance_mm", d)?;
            if d <= o.radius_mm {
                return Err(invalid(
                    "rig.distance_mm",
                    format!(
                        "is {d} mm, inside the object's bounding sphere ({} mm)",
                        o.radius_mm
                    ),
                ));
            }
        }
        let [a0, a1] = r.azimuth_deg;
        if !(a0.is_finite() && a1.is_finite() && a0 <= a1 && a1 - a0 < 360.0) {
            return Err(invalid(
                "rig.azimuth_deg",
                format!("is [{a0}, {a1}]: need min <= max, span < 360"),
            ));
        }
        let [e0, e1] = r.elevation_deg;
        if !(e0.is_finite() && e1.is_finite() && e0 <= e1 && e0 > -89.0 && e1 < 89.0) {
            return Err(invalid(
                "rig.elevation_deg",
                format!("is [{e0}, {e1}]: need -89 < min <= max < 89"),
            ));
        }
        if !(r.scale_margin.is_finite() && r.scale_margin >= 1.0) {
            return Err(invalid(
                "rig.scale_margin",
                format!("is {}, must be >= 1", r.scale_margin),
            ));
        }

        if self.render.spp == 0 || self.render.spp > 1024 {
            return Err(invalid(
                "render.spp",
                format!("is {}, must be in 1..=1024", self.render.spp),
            ));
        }
        colour("render.background", self.render.background)?;

        let g = &self.gt;
        positive("gt.spacing_mm", g.spacing_mm)?;
        positive("gt.obs_res_mm", g.obs_res_mm)?;
        if !(g.obs_dilate_mm.is_finite() && g.obs_dilate_mm >= 0.0) {
            return Err(invalid(
                "gt.obs_dilate_mm",
                format!("is {}, must be >= 0", g.obs_dilate_mm),
            ));
        }
        positive("gt.occlusion_eps_mm", g.occlusion_eps_mm)?;
        // Sampling finer than this on a 100 mm object makes hundreds of millions of points.
        let area_guess = 4.0 * std::f64::consts::PI * o.radius_mm * o.radius_mm;
        let n_guess = area_guess / (g.spacing_mm * g.spacing_mm);
        if n_guess > 2e8 {
            return Err(invalid(
                "gt.spacing_mm",
                format!(
                    "{} mm on a {} mm object would make ~{n_guess:.1e} points; use a coarser spacing",
                    g.spacing_mm, o.radius_mm
                ),
            ));
        }

        let e = &self.effects;
        let lambert = e.lambert().is_some();
        if let Some(s) = e.shading.as_ref().filter(|s| s.enabled) {
            if s.model == ShadingModel::Lambert {
                let d = s.direction;
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if !(n.is_finite() && n > 1e-9) {
                    return Err(invalid(
                        "effects.shading.direction",
                        format!("is {d:?}, not a direction"),
                    ));
                }
                unit_range("effects.shading.ambient", s.ambient)?;
                if !(s.diffuse.is_finite() && s.diffuse >= 0.0 && s.diffuse <= 4.0) {
                    return Err(invalid(
                        "effects.shading.diffuse",
                        format!("is {}, must lie in [0, 4]", s.diffuse),
                    ));
                }
            }
        }
        let needs_light = |key: &str| {
            invalid(
                key,
                "needs a light: add effects.shading with model = \"lambert\"",
            )
        };
        if let Some(s) = e.specular() {
            if !lambert {
                return Err(needs_light("effects.specular"));
            }
            if !(s.strength.is_finite() && (0.0..=4.0).contains(&s.strength)) {
                return Err(invalid(
                    "effects.specular.strength",
                    format!("is {}, must lie in [0, 4]", s.strength),
                ));
            }
            if !(s.exponent.is_finite() && s.exponent >= 1.0 && s.exponent <= 10000.0) {
                return Err(invalid(
                    "effects.specular.exponent",
                    format!("is {}, must lie in [1, 10000]", s.exponent),
                ));
            }
        }
        if let Some(s) = e.shadows() {
            if !lambert {
                return Err(needs_light("effects.shadows"));
            }
            positive("effects.shadows.offset_mm", s.offset_mm as f64)?;
        }
        if let Some(t) = e.texture() {
            positive("effects.texture.scale_mm", t.scale_mm as f64)?;
        }
        if let Some(x) = e.exposure() {
            if !(x.sigma.is_finite() && (0.0..=2.0).contains(&x.sigma)) {
                return Err(invalid(
                    "effects.exposure.sigma",
                    format!("is {}, must lie in [0, 2]", x.sigma),
                ));
            }
        }
        if let Some(j) = e.light_jitter() {
            if !lambert {
                return Err(needs_light("effects.light_jitter"));
            }
            if !(j.degrees.is_finite() && (0.0..=180.0).contains(&j.degrees)) {
                return Err(invalid(
                    "effects.light_jitter.degrees",
                    format!("is {}, must lie in [0, 180]", j.degrees),
                ));
            }
        }
        if let Some(p) = e.ground_plane() {
            if !(p.half_size.is_finite() && p.half_size >= 1.0 && p.half_size <= 100.0) {
                return Err(invalid(
                    "effects.ground_plane.half_size",
                    format!("is {}, must lie in [1, 100]", p.half_size),
                ));
            }
            positive("effects.ground_plane.checker_mm", p.checker_mm as f64)?;
            colour("effects.ground_plane.colors", p.colors[0])?;
            colour("effects.ground_plane.colors", p.colors[1])?;
        }
        super::degrade::parse_all(&e.degrade)?;
        Ok(())
    }
}
