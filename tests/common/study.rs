//! Fabricated study folders: the planned configurations with made-up metrics, for the
//! collector's tests (no training).

use neus_aug::study::plan::{run_dir, StudyPlan};
use std::path::Path;

/// Writes the planned `config.toml` and a fabricated `metrics.json` for every run of `plan`.
pub fn fabricate(
    dir: &Path,
    plan: &StudyPlan,
    cfgs: &[neus_aug::reconstruct::RunConfig],
    chamfer: impl Fn(&neus_aug::study::RunSpec) -> f64,
    train_time: impl Fn(&neus_aug::study::RunSpec) -> f64,
) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("study.toml"), plan.to_toml()).unwrap();
    for (r, c) in plan.runs.iter().zip(cfgs) {
        let rd = run_dir(dir, &r.id);
        std::fs::create_dir_all(&rd).unwrap();
        std::fs::write(rd.join("config.toml"), c.to_toml()).unwrap();
        let ch = chamfer(r);
        let reused = r.reuse_training_of.is_some();
        let m = serde_json::json!({
            "config_hash": r.training_hash,
            "chamfer": {"mean_d2s": ch * 0.4, "mean_s2d": ch * 0.6, "overall": ch / 2.0,
                        "chamfer_sum": ch, "gt_root": "x", "scan": 101},
            "psnr_heldout": 25.0, "ssim_heldout": 0.9,
            "train": {"iterations": c.train.iterations,
                      "resumed_from": if reused { Some(c.train.iterations) } else { None }},
            "timings_s": {"load": 1.0, "prepare": 0.5,
                          "train": if reused { 0.0 } else { train_time(r) },
                          "mesh": 2.0, "eval": 1.0, "render": 1.0, "total": 99.0},
        });
        std::fs::write(rd.join("metrics.json"), m.to_string()).unwrap();
    }
}
