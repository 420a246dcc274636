//! The accuracy-against-time study: one point per variant and the Pareto front.

use super::super::stats;
use super::layout::{m_train, Layout, Row};
use super::records::RunRecord;
use crate::study::plot::ReferenceFront;
use crate::study::StudyError;
use serde::Serialize;
use std::path::Path;

/// One pareto variant, averaged over seeds (and scenes).
#[derive(Clone, Debug, Serialize)]
pub(super) struct ParetoRow {
    pub(super) condition: String,
    pub(super) n: usize,
    pub(super) chamfer_mean: Option<f64>,
    pub(super) chamfer_std: Option<f64>,
    pub(super) time_to_mesh_mean: Option<f64>,
    pub(super) train_mean: Option<f64>,
    pub(super) mesh_mean: Option<f64>,
    pub(super) on_front: bool,
}

pub(super) fn pareto_points(lay: &Layout<'_>) -> Vec<ParetoRow> {
    let mut rows: Vec<ParetoRow> = lay
        .conditions
        .iter()
        .map(|c| {
            let row = Row {
                label: String::new(),
                condition: c.clone(),
                scene: None,
            };
            let recs: Vec<&RunRecord> = lay.records.iter().filter(|r| &r.condition == c).collect();
            let ch: Vec<f64> = recs.iter().filter_map(|r| r.chamfer_sum).collect();
            let tm: Vec<f64> = recs
                .iter()
                .filter(|r| r.chamfer_sum.is_some())
                .map(|r| r.time_to_mesh)
                .collect();
            let tr: Vec<f64> = recs.iter().filter_map(|r| m_train(r)).collect();
            let me: Vec<f64> = recs.iter().map(|r| r.time_mesh).collect();
            let _ = &row;
            ParetoRow {
                condition: c.clone(),
                n: ch.len(),
                chamfer_mean: stats::mean(&ch),
                chamfer_std: stats::sample_std(&ch),
                time_to_mesh_mean: stats::mean(&tm),
                train_mean: stats::mean(&tr),
                mesh_mean: stats::mean(&me),
                on_front: false,
            }
        })
        .collect();
    let pts: Vec<Option<(f64, f64)>> = rows
        .iter()
        .map(|r| Some((r.time_to_mesh_mean?, r.chamfer_mean?)))
        .collect();
    let front = pareto_front(&pts);
    for (r, f) in rows.iter_mut().zip(front) {
        r.on_front = f;
    }
    rows
}

/// Reads another pareto study's `pareto.csv` (the file, its report folder, or its study folder)
/// as a reference front for the plot: every row with a time and a Chamfer, and whether it is on
/// that study's front (recomputed from the points, so a hand-edited file stays consistent).
pub fn read_reference_front(path: &Path, label: &str) -> Result<ReferenceFront, StudyError> {
    let file = [
        path.to_path_buf(),
        path.join("pareto.csv"),
        path.join("report").join("pareto.csv"),
    ]
    .into_iter()
    .find(|p| p.is_file())
    .ok_or_else(|| StudyError::Folder {
        dir: path.to_path_buf(),
        problem: "no pareto.csv here, in report/ or as the path itself (a `study pareto` \
                  report is needed as the reference front)"
            .into(),
    })?;
    let text = std::fs::read_to_string(&file).map_err(|source| StudyError::Io {
        path: file.clone(),
        source,
    })?;
    let parse = |message: String| StudyError::Parse {
        path: file.clone(),
        message,
    };
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| parse("empty file".into()))?
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| parse(format!("no column `{name}` in the header")))
    };
    let (ct, cc) = (col("time_to_mesh_mean")?, col("chamfer_mean")?);
    let mut points = Vec::new();
    for (i, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |c: usize| -> Result<Option<f64>, StudyError> {
            match cells.get(c).copied().unwrap_or("") {
                "" => Ok(None),
                v => match v.parse::<f64>() {
                    Ok(x) if x.is_finite() => Ok(Some(x)),
                    _ => Err(parse(format!(
                        "row {}: `{v}` is not a finite number",
                        i + 2
                    ))),
                },
            }
        };
        if let (Some(t), Some(c)) = (num(ct)?, num(cc)?) {
            points.push((t, c));
        }
    }
    if points.is_empty() {
        return Err(parse("no row has both a time and a Chamfer".into()));
    }
    let on_front = pareto_front(&points.iter().copied().map(Some).collect::<Vec<_>>());
    Ok(ReferenceFront {
        label: label.to_string(),
        points,
        on_front,
    })
}

/// Which points are on the Pareto front of (time, error), both to be minimised: no other point
/// is at least as good in both and strictly better in one. `None` points are never on it.
pub fn pareto_front(pts: &[Option<(f64, f64)>]) -> Vec<bool> {
    pts.iter()
        .map(|p| {
            let Some((t, e)) = *p else { return false };
            !pts.iter()
                .flatten()
                .any(|&(t2, e2)| t2 <= t && e2 <= e && (t2 < t || e2 < e))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_matches_brute_force_definition() {
        let pts = [
            Some((1.0, 5.0)),
            Some((2.0, 3.0)),
            Some((3.0, 3.0)), // dominated by (2, 3)
            Some((4.0, 1.0)),
            None,
            Some((5.0, 2.0)), // dominated by (4, 1)
            Some((1.0, 5.0)), // a tie with the first: neither dominates
        ];
        assert_eq!(
            pareto_front(&pts),
            [true, true, false, true, false, false, true]
        );
    }

    #[test]
    fn reference_front_reads_a_report_and_refuses_bad_files() {
        let dir = std::env::temp_dir().join(format!("neus-aug-ref-front-{}", std::process::id()));
        let report = dir.join("report");
        std::fs::create_dir_all(&report).unwrap();
        std::fs::write(
            report.join("pareto.csv"),
            "variant,factor,value,n,chamfer_mean,chamfer_std,time_to_mesh_mean,train_mean,mesh_mean,on_front\n\
             centre,centre,,1,0.98,,150.0,148.0,2.0,false\n\
             iterations=250,iterations,250,1,2.5,,20.0,18.0,2.0,true\n\
             mc=128,mc,128,1,,,,,0.4,false\n\
             samples=512,samples,512,1,0.90,,240.0,238.0,2.0,true\n\
             slow,x,,1,1.2,,300.0,,,true\n",
        )
        .unwrap();
        // The study folder, the report folder and the file all work.
        for p in [dir.clone(), report.clone(), report.join("pareto.csv")] {
            let r = read_reference_front(&p, "old").unwrap();
            assert_eq!(r.label, "old");
            assert_eq!(
                r.points,
                [(150.0, 0.98), (20.0, 2.5), (240.0, 0.90), (300.0, 1.2)]
            );
            // The stored on_front column is not trusted: `slow` is dominated by `samples=512`.
            assert_eq!(r.on_front, [true, true, true, false]);
        }
        let bad = dir.join("bad.csv");
        std::fs::write(&bad, "variant,chamfer_mean\ncentre,1.0\n").unwrap();
        let e = read_reference_front(&bad, "x").unwrap_err().to_string();
        assert!(e.contains("time_to_mesh_mean"), "{e}");
        std::fs::write(&bad, "chamfer_mean,time_to_mesh_mean\nNaN,3\n").unwrap();
        let e = read_reference_front(&bad, "x").unwrap_err().to_string();
        assert!(e.contains("row 2") && e.contains("NaN"), "{e}");
        std::fs::write(&bad, "chamfer_mean,time_to_mesh_mean\n,3\n").unwrap();
        let e = read_reference_front(&bad, "x").unwrap_err().to_string();
        assert!(e.contains("no row"), "{e}");
        let e = read_reference_front(&dir.join("nowhere"), "x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no pareto.csv"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
