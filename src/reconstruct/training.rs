//! Stage 3, *train*: the start (the sphere, or a fit to the visual hull), then the training loop
//! with progress, checkpoints, and the depth prior: asked for by the configuration, or turned on
//! part-way through by its automatic switch (`train::depth_auto`), whose decision goes to
//! `depth_auto.json` so that a run resumed past the check reads it instead of checking again.

use super::folder::RunFolder;
use super::metrics::{HullInitSummary, TrainSummary};
use super::prepare::Prepared;
use super::progress::Progress;
use super::{say, write_atomic, ReconstructError, RunConfig, RunOptions};
use crate::mvs::{self, DepthMapsSummary};
use crate::render::model::NeusModel;
use crate::scene::Camera;
use crate::train::checkpoint::{self, TrainState};
use crate::train::depth::{DepthConfig, DepthPrior};
use crate::train::depth_auto::{self, AutoCheck};
use crate::train::hull;
use crate::train::{TrainData, Trainer};
use std::path::Path;
use std::time::Instant;

/// What training left: the final state and its summary for `metrics.json`.
pub(super) struct Trained {
    pub state: TrainState,
    pub summary: TrainSummary,
    pub secs: f64,
}

/// Stage 3 (see the module doc).
pub(super) fn train(
    cfg: &RunConfig,
    p: &Prepared,
    folder: &mut RunFolder,
    opts: &RunOptions,
) -> Result<Trained, ReconstructError> {
    let t = Instant::now();
    let quiet = opts.quiet;
    let (model, data) = (&p.model, &p.data);
    let cameras: Vec<Camera> = p.cameras().into_iter().cloned().collect();
    let mut trainer = Trainer::new(
        model,
        data,
        &cfg.train,
        cfg.seed,
        cfg.augment.seed ^ cfg.seed,
    );
    if cfg.train.pose_refine.enabled {
        trainer = trainer.with_pose_refinement(&cameras);
        if cfg.train.depth.enabled() {
            say(
                quiet,
                "note: the stereo depth prior asked for (train.depth) is computed before \
                 training, from the imported cameras, not the refined ones; its automatic \
                 switch (train.depth.auto) instead uses the cameras refined by its step",
            );
        }
    }
    let mut depth_maps = None;
    if cfg.train.depth.enabled() {
        let (prior, summary) = stereo_prior(&cfg.train.depth, &cameras, data, quiet);
        depth_maps = Some(summary);
        trainer = trainer.with_depth_prior(prior);
    }
    let iters = cfg.train.iterations;
    let switch = Switch::new(cfg, p, &folder.out, quiet);
    let mut hull_init = None;
    let mut state = match folder.resumed.take() {
        Some(s) => {
            say(quiet, format!("resuming from step {}", s.step));
            s
        }
        None => {
            let mut s = trainer.initial_state();
            hull_init = fit_hull_start(cfg, p, &mut s, quiet)?;
            s
        }
    };
    let resumed_from = (state.step > 0).then_some(state.step);
    let mut depth_auto = switch.recorded_or_check(cfg, model, &state, &cameras, data)?;
    if let Some(c) = depth_auto
        .as_ref()
        .filter(|c| c.triggered && state.step < iters)
    {
        depth_maps = Some(switch.turn_on(cfg, c, &cameras, data, &mut trainer)?);
    }
    let mut progress = Progress::new(iters, state.step, quiet);
    let (mut rays, mut samples) = (0u64, 0u64);
    let mut last = None;
    let t_loop = Instant::now();
    while state.step < iters {
        let report = trainer.step(&mut state)?;
        if switch.due(state.step) && depth_auto.is_none() {
            let check = switch.check(cfg, model, &state, &cameras, data)?;
            if check.triggered && state.step < iters {
                depth_maps = Some(switch.turn_on(cfg, &check, &cameras, data, &mut trainer)?);
            }
            depth_auto = Some(check);
        }
        rays += report.rays as u64;
        samples += report.out.n_samples as u64;
        if let Some(why) = &report.skipped {
            say(quiet, format!("step {}: {why}", report.step));
        }
        let secs = t_loop.elapsed().as_secs_f64().max(1e-9);
        let mut depth_note = report.depth.map_or(String::new(), |d| {
            let kept = if d.photo_kept > 0 {
                format!(", {} kept by the photo check", d.photo_kept)
            } else {
                String::new()
            };
            format!(
                " depth on {}/{} rays, carved {}{kept}",
                d.with_depth, d.rays, d.carved
            )
        });
        if let Some(ps) = report.pose {
            depth_note += &format!(
                " pose {:.3}° {:.3}",
                ps.mean_rotation.to_degrees(),
                ps.mean_translation * p.scene.normalization.scale
            );
        }
        progress.update(
            state.step,
            format!(
                "loss {:.4} psnr {:.2} inv_s {:.0} rays/s {:.0}{depth_note}",
                report.out.total,
                -10.0 * report.out.mse_all.max(1e-12).log10(),
                report.out.inv_s,
                rays as f64 / secs
            ),
        );
        last = Some(report);
        let every = cfg.train.checkpoint_every;
        let stop = opts.stop_after.is_some_and(|s| state.step >= s);
        if state.step == iters || stop || (every > 0 && state.step.is_multiple_of(every)) {
            let (path, text, hash) = (&folder.ckpt_path, &folder.config_toml, &folder.hash);
            checkpoint::save(path, &state, &model.layout, text, hash)?;
        }
        if stop {
            progress.finish();
            return Err(ReconstructError::Output {
                path: folder.out.clone(),
                problem: format!("stopped after step {} as asked (--stop-after)", state.step),
            });
        }
    }
    progress.finish();
    let train_secs = t_loop.elapsed().as_secs_f64();
    if resumed_from.is_none_or(|s| s < iters) && samples == 0 {
        return Err(ReconstructError::NothingTrained(format!(
            "{} training steps met no sample of the field: every ray missed the occupied part \
             of the region the scene's normalisation (cameras_sphere.npz scale_mat) puts the \
             object in, or the occupancy grid emptied it",
            iters - resumed_from.unwrap_or(0)
        )));
    }
    let summary = TrainSummary {
        iterations: iters,
        resumed_from,
        final_loss: last.as_ref().map_or(f64::NAN, |r| r.out.total),
        final_train_psnr: last
            .as_ref()
            .map_or(f64::NAN, |r| -10.0 * r.out.mse_all.max(1e-12).log10()),
        final_inv_s: model.inv_s(&state.params) as f64,
        skipped_steps: state.skipped_steps,
        rays,
        samples,
        samples_per_second: samples as f64 / train_secs.max(1e-9),
        train_views: p.train_idx.len(),
        heldout_views: p.heldout.clone(),
        hull_init,
        sphere_cover: p.sphere_cover,
        depth_maps,
        depth_last: last.as_ref().and_then(|r| r.depth),
        depth_auto,
        depth_auto_skipped: switch.skipped,
        error_map: state.error_map.as_ref().map(|m| m.summary()),
        pose_refine: match &state.pose {
            Some(ps) => Some(super::refined::write_refined(
                p,
                cfg.data.downscale,
                ps,
                &folder.out,
            )?),
            None => None,
        },
    };
    let secs = t.elapsed().as_secs_f64();
    say(
        quiet,
        format!(
            "trained {iters} steps in {secs:.1} s ({:.0} samples/s), inv_s {:.0}",
            summary.samples_per_second, summary.final_inv_s
        ),
    );
    Ok(Trained {
        state,
        summary,
        secs,
    })
}

/// The visual-hull start (`train::hull`), when the start is the hull: the SDF fitted to it.
fn fit_hull_start(
    cfg: &RunConfig,
    p: &Prepared,
    s: &mut TrainState,
    quiet: bool,
) -> Result<Option<HullInitSummary>, ReconstructError> {
    let Some(sdf) = &p.hull_target else {
        return Ok(None);
    };
    let t = Instant::now();
    let ic = &cfg.train.init;
    let model = &p.model;
    let active = model.config.schedule(0).active_levels;
    let rep = hull::fit(model, &mut s.params, sdf, ic, active, cfg.seed)?;
    let mm = p.scene.normalization.scale;
    let h = HullInitSummary {
        resolution: ic.resolution,
        inside_share: rep.inside_share,
        fit_error_first_mm: rep.l1_first * mm,
        fit_error_last_mm: rep.l1_last * mm,
        seconds: t.elapsed().as_secs_f64(),
    };
    say(
        quiet,
        format!(
            "visual hull: {:.1} % of the {}³ grid inside; SDF fit {} steps, mean |error| {:.2} → \
             {:.2} mm, {:.1} s",
            100.0 * h.inside_share,
            h.resolution,
            ic.steps,
            h.fit_error_first_mm,
            h.fit_error_last_mm,
            h.seconds
        ),
    );
    Ok(Some(h))
}

/// The depth prior's automatic switch in this run.
struct Switch {
    /// Whether it checks in this run (on, the prior not asked for, a mask on every view).
    on: bool,
    /// The step after which it checks.
    step: u64,
    path: std::path::PathBuf,
    quiet: bool,
    /// Why it does not check although it is on (its step falls outside the run).
    skipped: Option<String>,
}

impl Switch {
    fn new(cfg: &RunConfig, p: &Prepared, out: &Path, quiet: bool) -> Self {
        let a = &cfg.train.depth.auto;
        let wanted = a.enabled && !cfg.train.depth.enabled() && p.all_masked;
        let step = a.check_step(cfg.train.iterations);
        let skipped = (wanted && step.is_none()).then(|| {
            let why = format!(
                "the depth prior's automatic switch does not check: its step (train.depth.auto.at \
                 = {} of {} steps, at least min_step = {}) is not before the run's last step",
                a.at, cfg.train.iterations, a.min_step
            );
            eprintln!("note: {why}");
            why
        });
        Self {
            on: wanted && step.is_some(),
            step: step.unwrap_or(u64::MAX),
            path: out.join("depth_auto.json"),
            quiet,
            skipped,
        }
    }

    /// Whether the check is due after the step that just brought the state to `step`.
    fn due(&self, step: u64) -> bool {
        self.on && step == self.step
    }

    /// For a run resumed at or past the check: the decision recorded in `depth_auto.json`, or
    /// (no readable record, steps left to train) a check of the resumed field now.
    fn recorded_or_check(
        &self,
        cfg: &RunConfig,
        model: &NeusModel,
        state: &TrainState,
        cameras: &[Camera],
        data: &TrainData,
    ) -> Result<Option<AutoCheck>, ReconstructError> {
        if !self.on || state.step < self.step {
            return Ok(None);
        }
        let recorded = std::fs::read_to_string(&self.path)
            .ok()
            .and_then(|t| serde_json::from_str::<AutoCheck>(&t).ok());
        match recorded {
            Some(c) => Ok(Some(c)),
            None if state.step < cfg.train.iterations => {
                say(
                    self.quiet,
                    format!(
                        "depth prior, automatic switch: no record of the check at step {} ({} \
                         missing or unreadable); checking the resumed field at step {}",
                        self.step,
                        self.path.display(),
                        state.step
                    ),
                );
                self.check(cfg, model, state, cameras, data).map(Some)
            }
            // Nothing left to train: nothing to decide.
            None => Ok(None),
        }
    }

    /// The prior as the switch turns it on, attached to the trainer; its stereo's summary.
    /// Its stereo uses the cameras of `check` (refined by the check's step when pose refinement
    /// is on, [`Self::cameras_of`]).
    fn turn_on(
        &self,
        cfg: &RunConfig,
        check: &AutoCheck,
        imported: &[Camera],
        data: &TrainData,
        trainer: &mut Trainer,
    ) -> Result<DepthMapsSummary, ReconstructError> {
        let on = cfg.train.depth.switched_on(self.step);
        let cameras = self.cameras_of(check.pose.as_ref(), imported)?;
        let (prior, summary) = stereo_prior(&on, &cameras, data, self.quiet);
        trainer.set_depth_prior(prior);
        Ok(summary)
    }

    /// The training cameras as pose refinement had them at the check: `imported` with the
    /// corrections of `pose` (none: refinement off). A recorded `pose` that does not fit the
    /// scene's cameras is an error naming the record.
    fn cameras_of(
        &self,
        pose: Option<&crate::train::pose_refine::PoseSnapshot>,
        imported: &[Camera],
    ) -> Result<Vec<Camera>, ReconstructError> {
        let Some(p) = pose else {
            return Ok(imported.to_vec());
        };
        p.corrected(imported)
            .ok_or_else(|| ReconstructError::Output {
                path: self.path.clone(),
                problem: format!(
                    "the pose corrections recorded there ({} views, {} focal scales) do not fit \
                 this scene's {} training cameras; delete the file to check again",
                    p.views.len(),
                    p.focal.len(),
                    imported.len()
                ),
            })
    }

    /// The check on the field of `state` (`train::depth_auto`): sweeps its views, marches
    /// their rays through the field, decides, says so and writes the decision to
    /// `depth_auto.json`. With pose refinement on, the views are those the state's corrections
    /// give (the field was trained through them), and the record keeps the corrections.
    fn check(
        &self,
        cfg: &RunConfig,
        model: &NeusModel,
        state: &TrainState,
        imported: &[Camera],
        data: &TrainData,
    ) -> Result<AutoCheck, ReconstructError> {
        let a = &cfg.train.depth.auto;
        let t0 = Instant::now();
        let pose = state.pose.as_ref().map(|p| p.snapshot());
        let cameras = &self.cameras_of(pose.as_ref(), imported)?;
        let views = depth_auto::check_views(cameras.len(), a.views);
        let (imgs, masks) = (data.views(), data.masks());
        let maps = mvs::sweep_depths(&cfg.train.depth.mvs, cameras, imgs, masks, &views);
        let cams: Vec<&Camera> = views.iter().map(|&i| &cameras[i]).collect();
        let active = model.config.schedule(state.step).active_levels;
        let sdf = |p: &[[f32; 3]]| model.sdf(&state.params, p, active);
        let r = model.config.render.radius as f64;
        let (rays, in_front) =
            depth_auto::solid_in_front(&sdf, &cams, &maps, r, a.margin as f64, a.step as f64);
        let share = if rays > 0 {
            in_front as f64 / rays as f64
        } else {
            0.0
        };
        let triggered = rays >= a.min_rays && share >= a.share as f64;
        let check = AutoCheck {
            step: state.step,
            views,
            rays,
            in_front,
            share,
            margin: a.margin,
            threshold: a.share,
            triggered,
            seconds: t0.elapsed().as_secs_f64(),
            pose,
        };
        let verdict = if triggered {
            "the field has closed space the stereo sees through (a cavity's lid): depth prior on"
                .to_string()
        } else if rays < a.min_rays {
            format!(
                "fewer than {} rays with a stereo depth: depth prior stays off",
                a.min_rays
            )
        } else {
            "depth prior stays off".to_string()
        };
        say(
            self.quiet,
            format!(
                "depth prior, automatic switch at step {}: {in_front} of {rays} rays ({:.1} %, \
                 threshold {:.1} %) have solid more than {} (normalised units) in front of their \
                 stereo depth, {:.1} s; {verdict}",
                check.step,
                100.0 * share,
                100.0 * a.share,
                a.margin,
                check.seconds
            ),
        );
        let text = serde_json::to_string_pretty(&check).expect("the check serialises");
        write_atomic(&self.path, &text)?;
        Ok(check)
    }
}

/// The stereo of the depth prior `depth` over the training views, and the prior on it
/// (`train::depth`), with what the stereo found said and summarised.
fn stereo_prior(
    depth: &DepthConfig,
    cameras: &[Camera],
    data: &TrainData,
    quiet: bool,
) -> (DepthPrior, DepthMapsSummary) {
    let t_mvs = Instant::now();
    say(
        quiet,
        format!(
            "depth prior: plane-sweep stereo of {} views ({} planes)",
            cameras.len(),
            depth.mvs.planes
        ),
    );
    let maps = mvs::depth_maps(&depth.mvs, cameras, data.views(), data.masks());
    let summary = maps.summary(t_mvs.elapsed().as_secs_f64());
    say(
        quiet,
        format!(
            "depth prior: depth on {} of {} pixels ({:.1} %; {} by the fusion fill, {} by the \
             hole fill) in {:.1} s",
            summary.with_depth,
            summary.considered,
            100.0 * summary.with_depth as f64 / summary.considered.max(1) as f64,
            summary.filled,
            summary.hole_filled,
            summary.seconds
        ),
    );
    if summary.with_depth == 0 {
        say(
            false,
            "warning: the depth prior found no depth (no texture, or no view overlap): it does \
             nothing",
        );
    }
    let mut prior = DepthPrior::new(depth.clone(), cameras.to_vec(), maps);
    if depth.photo_check {
        let images = data.views();
        prior = prior.with_photo(mvs::PhotoCost::new(
            &depth.photo_mvs(),
            cameras,
            images,
            data.masks(),
        ));
    }
    (prior, summary)
}
