//! Stage 7, *render*: the held-out views rendered at test time (identity embedding, `p = 0`),
//! written to `renders/` beside their ground truth and normal maps, and scored: PSNR, SSIM,
//! silhouette IoU and, where the scene folder has its true mesh, the normal angular error.

use super::normal_error;
use super::prepare::Prepared;
use super::{io_err, say, ReconstructError, RunConfig, ViewMetrics};
use crate::render::model::RayBatch;
use crate::scene::RgbImage;
use crate::train::checkpoint::TrainState;
use crate::train::data::camera_rays;
use crate::train::metrics::{psnr, ssim};
use dtu_eval::TriMesh;
use std::path::Path;
use std::time::Instant;

/// The held-out figures.
pub(super) struct Heldout {
    pub views: Vec<ViewMetrics>,
    /// Pixel-weighted mean normal error over the views (degrees).
    pub normal_error_deg: Option<f64>,
    pub psnr: Option<f64>,
    pub ssim: Option<f64>,
    pub mask_iou: Option<f64>,
    pub secs: f64,
}

/// Stage 7 (see the module doc). `truth_mesh`: the scene's `gt_mesh.ply` as stage 6 read it.
pub(super) fn render_heldout(
    cfg: &RunConfig,
    p: &Prepared,
    state: &TrainState,
    truth_mesh: Option<Result<TriMesh, dtu_eval::ply::PlyError>>,
    out: &Path,
    quiet: bool,
) -> Result<Heldout, ReconstructError> {
    let t = Instant::now();
    let renders = out.join("renders");
    let mut views = Vec::new();
    if !p.heldout.is_empty() {
        std::fs::create_dir_all(&renders).map_err(io_err(&renders))?;
    }
    let model = &p.model;
    let k = cfg.data.render_downscale as usize;
    let sched = model.config.inference_schedule(cfg.train.iterations);
    // A diagnostic, as the seen floor is: a true mesh that cannot be read costs the normal
    // error (with a warning), not the run that has already trained.
    let gt_normals = match truth_mesh.filter(|_| !p.heldout.is_empty()) {
        None => None,
        Some(Ok(m)) => normal_error::GtNormals::new(&m, &p.scene.normalization),
        // The PLY reader's error names the file already.
        Some(Err(e)) => {
            eprintln!(
                "warning: no held-out normal error ({})",
                e.to_string().trim_end()
            );
            None
        }
    };
    let (mut nerr_sum, mut nerr_px) = (0.0f64, 0usize);
    for &v in &p.heldout {
        let view = &p.scene.views[v];
        let cam = view.camera.downscaled(k as u32);
        let (origins, dirs) = camera_rays(&cam);
        let (w, h) = (cam.width as usize, cam.height as usize);
        let codes = vec![0u32; origins.len()];
        let pz = vec![0f32; origins.len()];
        let batch = RayBatch {
            origins: &origins,
            dirs: &dirs,
            codes: &codes,
            p: &pz,
        };
        let occ = model.config.render.occupancy.enabled.then_some(&state.occ);
        let o = model.render(&state.params, &batch, sched, occ)?;
        let bg = model.config.render.background;
        let mut gt = view.image.downscaled(k);
        if let Some(m) = view.mask.as_ref().filter(|_| cfg.data.masks) {
            let m = m.downscaled(k);
            for (px, mv) in gt.data.chunks_exact_mut(3).zip(&m.data) {
                for (v, b) in px.iter_mut().zip(bg) {
                    *v = *v * mv + b * (1.0 - mv);
                }
            }
        }
        let rgb = RgbImage {
            width: w,
            height: h,
            data: o.rgb.iter().flatten().copied().collect(),
        };
        let normal = normal_error::normal_image(w, h, &o.normal, &o.opacity, bg);
        rgb.save(&renders.join(format!("view{v:03}_rgb.png")))?;
        normal.save(&renders.join(format!("view{v:03}_normal.png")))?;
        gt.save(&renders.join(format!("view{v:03}_gt.png")))?;
        let normal_error_deg = gt_normals.as_ref().and_then(|g| {
            let (s, n) = g.angular_error(&origins, &dirs, &o.normal, &o.opacity);
            nerr_sum += s;
            nerr_px += n;
            (n > 0).then(|| s / n as f64)
        });
        // Silhouette agreement: a membrane across a hole, or a floater, is opacity where the
        // held-out mask says background.
        let mask_iou = view.mask.as_ref().map(|m| {
            let m = m.downscaled(k);
            let (mut inter, mut union) = (0usize, 0usize);
            for (&mv, &op) in m.data.iter().zip(&o.opacity) {
                let (a, b) = (mv > 0.5, op > 0.5);
                inter += (a && b) as usize;
                union += (a || b) as usize;
            }
            if union == 0 {
                1.0
            } else {
                inter as f64 / union as f64
            }
        });
        views.push(ViewMetrics {
            view: v,
            psnr: psnr(&rgb, &gt),
            ssim: ssim(&rgb, &gt),
            normal_error_deg,
            mask_iou,
        });
    }
    let mean = |f: &dyn Fn(&ViewMetrics) -> Option<f64>| -> Option<f64> {
        let v: Vec<f64> = views.iter().filter_map(f).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    let h = Heldout {
        psnr: mean(&|m| Some(m.psnr)),
        ssim: mean(&|m| m.ssim),
        mask_iou: mean(&|m| m.mask_iou),
        normal_error_deg: (nerr_px > 0).then(|| nerr_sum / nerr_px as f64),
        secs: t.elapsed().as_secs_f64(),
        views,
    };
    if let Some(psnr) = h.psnr {
        say(
            quiet,
            format!(
                "held-out views {:?}: PSNR {psnr:.2} dB, SSIM {:.4}",
                p.heldout,
                h.ssim.unwrap_or(f64::NAN)
            ),
        );
    }
    Ok(h)
}
