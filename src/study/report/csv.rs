//! `runs.csv` and `pareto.csv`: one row per run or variant, floats in Rust's shortest
//! round-trip form, empty fields for missing values.

use super::pareto::ParetoRow;
use super::records::RunRecord;
use std::fmt::Write as _;

pub(super) fn csv_opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| x.to_string())
}

pub(super) fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// One row per run. The geometry columns follow when any record has them
/// ([`RunRecord::geometry`]), so older studies keep their columns.
pub(super) fn runs_csv(records: &[RunRecord]) -> String {
    let geometry = records.iter().any(|r| r.geometry.is_some());
    let mut s = String::from(
        "id,scene,condition,arm,seed,preset,views_fraction,degrade,chamfer_sum,accuracy,\
         completeness,overall,psnr,ssim,iterations,resumed_from,reused_training,time_load,\
         time_prepare,time_train,time_mesh,time_eval,time_render,time_total,time_to_mesh",
    );
    if geometry {
        s.push_str(
            ",floor_mm,ratio_to_floor,genus,gt_genus,genus_matches,components_raw,components,\
             normal_error_deg,chamfer_closed,depth_prior,floor_seen_mm,ratio_to_floor_seen",
        );
    }
    s.push('\n');
    let opt = |v: Option<String>| v.unwrap_or_default();
    for r in records {
        let f = [
            csv_field(&r.id),
            csv_field(&r.scene),
            csv_field(&r.condition),
            r.arm.clone(),
            r.seed.to_string(),
            r.preset.clone(),
            csv_opt(r.views_fraction),
            csv_field(r.degrade.as_deref().unwrap_or("")),
            csv_opt(r.chamfer_sum),
            csv_opt(r.accuracy),
            csv_opt(r.completeness),
            csv_opt(r.overall),
            csv_opt(r.psnr),
            csv_opt(r.ssim),
            r.iterations.to_string(),
            r.resumed_from.map_or(String::new(), |x| x.to_string()),
            r.reused_training.to_string(),
            r.time_load.to_string(),
            r.time_prepare.to_string(),
            r.time_train.to_string(),
            r.time_mesh.to_string(),
            r.time_eval.to_string(),
            r.time_render.to_string(),
            r.time_total.to_string(),
            r.time_to_mesh.to_string(),
        ];
        s.push_str(&f.join(","));
        if geometry {
            let g = r.geometry.clone().unwrap_or_default();
            let f = [
                csv_opt(g.floor_mm),
                csv_opt(g.ratio_to_floor),
                opt(g.genus.map(|x| x.to_string())),
                opt(g.gt_genus.map(|x| x.to_string())),
                opt(g.genus_matches.map(|x| x.to_string())),
                opt(g.components_raw.map(|x| x.to_string())),
                opt(g.components.map(|x| x.to_string())),
                csv_opt(g.normal_error_deg),
                csv_opt(g.chamfer_closed),
                csv_field(g.depth_prior.as_deref().unwrap_or("")),
                csv_opt(g.floor_seen),
                csv_opt(g.ratio_to_floor_seen),
            ];
            s.push(',');
            s.push_str(&f.join(","));
        }
        s.push('\n');
    }
    s
}

pub(super) fn pareto_csv(rows: &[ParetoRow]) -> String {
    let mut s = String::from(
        "variant,factor,value,n,chamfer_mean,chamfer_std,time_to_mesh_mean,train_mean,mesh_mean,on_front\n",
    );
    for r in rows {
        let (factor, value) = r
            .condition
            .split_once('=')
            .map_or((r.condition.as_str(), ""), |(f, v)| (f, v));
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.condition),
            csv_field(factor),
            csv_field(value),
            r.n,
            csv_opt(r.chamfer_mean),
            csv_opt(r.chamfer_std),
            csv_opt(r.time_to_mesh_mean),
            csv_opt(r.train_mean),
            csv_opt(r.mesh_mean),
            r.on_front
        );
    }
    s
}
