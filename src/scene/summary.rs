//! What `neus-aug inspect` reports about a scene: the first look a user takes at new data.

use super::dtu::Scene;
use serde::Serialize;

/// `[min, max]` of a quantity over the views.
pub type Range = [f64; 2];

/// A scene's vital statistics. Lengths are in normalised units unless the name says `_mm`.
#[derive(Clone, Debug, Serialize)]
pub struct SceneSummary {
    /// The scene folder.
    pub root: String,
    /// Number of views.
    pub n_views: usize,
    /// Distinct image sizes `(width, height)`.
    pub resolutions: Vec<(usize, usize)>,
    /// Focal lengths and principal point (pixels).
    pub fx: Range,
    pub fy: Range,
    pub cx: Range,
    pub cy: Range,
    /// Horizontal field of view (degrees).
    pub fov_x_deg: Range,
    /// Distance of the camera centres from the normalised origin (normalised units; the object
    /// region is the unit sphere, so values must exceed 1).
    pub camera_distance: Range,
    /// The same in world mm.
    pub camera_distance_mm: Range,
    /// Largest angle between two viewing directions towards the origin (degrees).
    pub max_baseline_angle_deg: f64,
    /// Whether masks were found.
    pub has_masks: bool,
    /// Per-view fraction of pixels inside the mask (`> 0.5`), in view order; empty without masks.
    pub mask_coverage: Vec<f64>,
    /// Views whose mask is empty (no object pixel): training on them only teaches background.
    pub empty_masks: Vec<usize>,
    /// `s` of `X_world = s·X_norm + c` (mm per normalised unit).
    pub scale_mm: f64,
    /// `c` (mm).
    pub center_mm: [f64; 3],
    /// False if some `scale_mat_i` differs from `scale_mat_0`.
    pub scale_mats_consistent: bool,
    /// Per view: `K` (row-major 3×3), the camera-to-world pose `[Rᵀ | C]` (row-major 3×4, OpenCV
    /// axes) and the centre `C`, normalised space. For cross-checks (`scripts/crosscheck_cameras.py`).
    pub cameras: Vec<CameraDump>,
}

/// One camera, row-major, normalised space.
#[derive(Clone, Debug, Serialize)]
pub struct CameraDump {
    pub image: String,
    pub k: [[f64; 3]; 3],
    pub c2w: [[f64; 4]; 3],
    pub center: [f64; 3],
}

fn range(values: impl Iterator<Item = f64>) -> Range {
    values.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| {
        [lo.min(v), hi.max(v)]
    })
}

impl SceneSummary {
    /// Summarises a loaded scene.
    pub fn of(scene: &Scene) -> Self {
        let views = &scene.views;
        let cams = || views.iter().map(|v| &v.camera);
        let mut resolutions: Vec<(usize, usize)> = views
            .iter()
            .map(|v| (v.image.width, v.image.height))
            .collect();
        resolutions.sort();
        resolutions.dedup();
        let dirs: Vec<_> = cams().map(|c| -c.center.normalize()).collect();
        let mut max_angle: f64 = 0.0;
        for (i, a) in dirs.iter().enumerate() {
            for b in &dirs[i + 1..] {
                max_angle = max_angle.max(a.dot(b).clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
        let mask_coverage: Vec<f64> = views
            .iter()
            .filter_map(|v| v.mask.as_ref().map(|m| m.coverage()))
            .collect();
        let s = scene.normalization.scale;
        Self {
            root: scene.root.display().to_string(),
            n_views: views.len(),
            resolutions,
            fx: range(cams().map(|c| c.k[(0, 0)])),
            fy: range(cams().map(|c| c.k[(1, 1)])),
            cx: range(cams().map(|c| c.k[(0, 2)])),
            cy: range(cams().map(|c| c.k[(1, 2)])),
            fov_x_deg: range(cams().map(|c| c.fov_degrees().0)),
            camera_distance: range(cams().map(|c| c.center.norm())),
            camera_distance_mm: range(cams().map(|c| c.center.norm() * s)),
            max_baseline_angle_deg: max_angle,
            has_masks: views.iter().any(|v| v.mask.is_some()),
            empty_masks: views
                .iter()
                .filter(|v| v.mask.as_ref().is_some_and(|m| m.coverage() == 0.0))
                .map(|v| v.index)
                .collect(),
            mask_coverage,
            scale_mm: s,
            center_mm: scene.normalization.center,
            scale_mats_consistent: scene.scale_mats_consistent,
            cameras: views
                .iter()
                .map(|v| {
                    let c = &v.camera;
                    let c2w = c.c2w();
                    CameraDump {
                        image: v.image_path.display().to_string(),
                        k: std::array::from_fn(|i| std::array::from_fn(|j| c.k[(i, j)])),
                        c2w: std::array::from_fn(|i| std::array::from_fn(|j| c2w[(i, j)])),
                        center: [c.center.x, c.center.y, c.center.z],
                    }
                })
                .collect(),
        }
    }

    /// A human-readable report (what `neus-aug inspect` prints).
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let r = |x: Range| format!("{:.2} .. {:.2}", x[0], x[1]);
        let mut s = String::new();
        let _ = writeln!(s, "scene        {}", self.root);
        let _ = writeln!(s, "views        {}", self.n_views);
        let res: Vec<String> = self
            .resolutions
            .iter()
            .map(|(w, h)| format!("{w}×{h}"))
            .collect();
        let _ = writeln!(s, "resolution   {}", res.join(", "));
        let _ = writeln!(s, "fx, fy (px)  {}  |  {}", r(self.fx), r(self.fy));
        let _ = writeln!(s, "cx, cy (px)  {}  |  {}", r(self.cx), r(self.cy));
        let _ = writeln!(s, "fov x (deg)  {}", r(self.fov_x_deg));
        let _ = writeln!(
            s,
            "camera dist  {} (normalised)  |  {} mm",
            r(self.camera_distance),
            r(self.camera_distance_mm)
        );
        let _ = writeln!(
            s,
            "max angle    {:.1}° between viewing directions",
            self.max_baseline_angle_deg
        );
        if self.has_masks {
            let cov = range(self.mask_coverage.iter().copied());
            let mean =
                self.mask_coverage.iter().sum::<f64>() / self.mask_coverage.len().max(1) as f64;
            let _ = writeln!(
                s,
                "masks        object covers {:.1}% .. {:.1}% of each image (mean {:.1}%)",
                100.0 * cov[0],
                100.0 * cov[1],
                100.0 * mean
            );
            if !self.empty_masks.is_empty() {
                let _ = writeln!(
                    s,
                    "WARNING      empty masks in views {:?}",
                    self.empty_masks
                );
            }
        } else {
            let _ = writeln!(
                s,
                "masks        none (train without mask loss; cull the mesh before scoring)"
            );
        }
        let c = self.center_mm;
        let _ = writeln!(
            s,
            "normalise    X_world = {:.4} · X_norm + ({:.3}, {:.3}, {:.3}) mm",
            self.scale_mm, c[0], c[1], c[2]
        );
        if !self.scale_mats_consistent {
            let _ = writeln!(
                s,
                "WARNING      scale_mat_i differ between views; scale_mat_0 maps meshes back"
            );
        }
        if self.camera_distance[0] <= 1.0 {
            let _ = writeln!(
                s,
                "WARNING      a camera lies inside the unit sphere: check scale_mat"
            );
        }
        s
    }
}
