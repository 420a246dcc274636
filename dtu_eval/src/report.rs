//! What an evaluation reports: the four figures (each labelled), the counts at every stage, the
//! parameters and seed, and the time of every stage. Serialised as JSON by `dtu-eval --json`.

use serde::{Deserialize, Serialize};
use std::time::Instant;

/// The result of one evaluation. Distances in the inputs' unit (mm for DTU).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Accuracy: mean distance from the (sampled, filtered) mesh to the reference, over the
    /// distances below `max_dist` (DTUeval-python's `mean_d2s`).
    pub mean_d2s: f64,
    /// Completeness: mean distance from the reference to the mesh, over the distances below
    /// `max_dist` (DTUeval-python's `mean_s2d`).
    pub mean_s2d: f64,
    /// `(mean_d2s + mean_s2d) / 2`: what DTUeval-python prints as "overall".
    pub overall: f64,
    /// `mean_d2s + mean_s2d`: the Chamfer figure the paper (Pérez et al.) reports.
    pub chamfer_sum: f64,
    /// The mesh (or point cloud) evaluated.
    pub mesh: String,
    /// Mode-specific inputs, parameters and counts.
    #[serde(flatten)]
    pub details: Details,
    /// Seed of the shuffle before downsampling.
    pub seed: u64,
    /// Wall time of each stage, in order.
    pub timings_s: Vec<StageTime>,
    /// `dtu_eval` version that produced the report.
    pub version: String,
}

/// Mode-specific part of a [`Report`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum Details {
    /// The DTU protocol against a scan's ground truth.
    Dtu {
        scan: u32,
        gt_root: String,
        params: DtuParams,
        counts: DtuCounts,
    },
    /// Two point sets (or meshes) without DTU masks.
    Plain {
        reference: String,
        params: PlainParams,
        counts: PlainCounts,
    },
}

/// Parameters of the DTU protocol; defaults are DTUeval-python's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DtuParams {
    /// Sampling density and downsampling radius (mm): `--downsample_density`, 0.2.
    pub density: f64,
    /// Margin around the observation box (mm): `--patch_size`, 60 (below; twice above).
    pub patch_size: f64,
    /// Outlier cut (mm): distances `>= max_dist` are left out of the means; 20.
    pub max_dist: f64,
}

impl Default for DtuParams {
    fn default() -> Self {
        Self {
            density: 0.2,
            patch_size: 60.0,
            max_dist: 20.0,
        }
    }
}

/// Point counts at each stage of the DTU protocol.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DtuCounts {
    pub mesh_vertices: u64,
    pub mesh_faces: u64,
    /// Vertices plus surface samples.
    pub sampled: u64,
    /// After greedy radius downsampling.
    pub downsampled: u64,
    /// In the observation box with its patch margin (`data_in`: the targets of `s2d`).
    pub in_box: u64,
    /// In an observed voxel of `ObsMask` (`data_in_obs`: the sources of `d2s`).
    pub in_obs: u64,
    pub gt_points: u64,
    /// Ground-truth points above the plane (the sources of `s2d`).
    pub gt_above_plane: u64,
    /// `d2s` distances below `max_dist` (averaged into `mean_d2s`).
    pub d2s_below_max: u64,
    /// `s2d` distances below `max_dist` (averaged into `mean_s2d`).
    pub s2d_below_max: u64,
}

/// Parameters of the plain mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlainParams {
    /// Sampling density for inputs with faces (their unit).
    pub density: f64,
    /// Greedy downsampling radius applied to both sets, if any.
    pub downsample: Option<f64>,
    /// Outlier cut, if any (distances `>= max_dist` left out of the means).
    pub max_dist: Option<f64>,
}

/// Point counts of the plain mode.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlainCounts {
    /// Points of the evaluated set after sampling (vertices, plus samples when it has faces).
    pub data_points: u64,
    /// ... after downsampling (equal when none).
    pub data_used: u64,
    pub ref_points: u64,
    pub ref_used: u64,
    pub d2s_below_max: u64,
    pub s2d_below_max: u64,
}

/// The wall time of one stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
}

/// Collects [`StageTime`]s: `lap("name")` closes the stage that ran since the last lap.
#[derive(Debug)]
pub struct Stopwatch {
    last: Instant,
    stages: Vec<StageTime>,
}

impl Default for Stopwatch {
    fn default() -> Self {
        Self::new()
    }
}

impl Stopwatch {
    pub fn new() -> Self {
        Self {
            last: Instant::now(),
            stages: Vec::new(),
        }
    }

    /// Records the time since the previous lap (or creation) under `stage`.
    pub fn lap(&mut self, stage: &str) {
        let now = Instant::now();
        self.stages.push(StageTime {
            stage: stage.to_string(),
            seconds: (now - self.last).as_secs_f64(),
        });
        self.last = now;
    }

    /// Restarts the clock without recording (time spent outside any stage).
    pub fn skip(&mut self) {
        self.last = Instant::now();
    }

    pub fn into_stages(self) -> Vec<StageTime> {
        self.stages
    }
}

impl Report {
    /// A human-readable summary: the four figures, each labelled, then counts and timings.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let unit = match self.details {
            Details::Dtu { .. } => " mm",
            Details::Plain { .. } => "",
        };
        match &self.details {
            Details::Dtu { scan, gt_root, .. } => s.push_str(&format!(
                "DTU scan {scan}: {} against {gt_root}\n",
                self.mesh
            )),
            Details::Plain { reference, .. } => {
                s.push_str(&format!("{} against {reference}\n", self.mesh))
            }
        }
        s.push_str(&format!(
            "  accuracy     mean_d2s (mesh -> reference)      {:.6}{unit}\n\
             \x20 completeness mean_s2d (reference -> mesh)      {:.6}{unit}\n\
             \x20 overall      (acc + comp) / 2 (DTUeval-python) {:.6}{unit}\n\
             \x20 chamfer_sum  acc + comp (the paper)            {:.6}{unit}\n",
            self.mean_d2s, self.mean_s2d, self.overall, self.chamfer_sum
        ));
        match &self.details {
            Details::Dtu {
                counts: c,
                params: p,
                ..
            } => s.push_str(&format!(
                "  points: {} vertices / {} faces -> sampled {} -> downsampled {} -> in box {} -> \
                 observed {}; GT {} -> above plane {}; below {} mm: d2s {}, s2d {}\n",
                c.mesh_vertices,
                c.mesh_faces,
                c.sampled,
                c.downsampled,
                c.in_box,
                c.in_obs,
                c.gt_points,
                c.gt_above_plane,
                p.max_dist,
                c.d2s_below_max,
                c.s2d_below_max
            )),
            Details::Plain { counts: c, .. } => s.push_str(&format!(
                "  points: data {} (used {}), reference {} (used {}); below max: d2s {}, s2d {}\n",
                c.data_points,
                c.data_used,
                c.ref_points,
                c.ref_used,
                c.d2s_below_max,
                c.s2d_below_max
            )),
        }
        let total: f64 = self.timings_s.iter().map(|t| t.seconds).sum();
        s.push_str(&format!("  seed {}; time {total:.3} s (", self.seed));
        let parts: Vec<String> = self
            .timings_s
            .iter()
            .map(|t| format!("{} {:.3}", t.stage, t.seconds))
            .collect();
        s.push_str(&parts.join(", "));
        s.push_str(")\n");
        s
    }
}
