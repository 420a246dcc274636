//! Training checkpoints in `safetensors`, loadable from Python
//! (`safetensors.numpy.load_file`), written atomically.
//!
//! Tensors (all little-endian):
//! - `params.<group>`: f32, the group's shape (`hash_grid`, `sdf_mlp`, `color_mlp`, `variance`,
//!   `appearance`, `bg_density`, `bg_color` with a learned background; see
//!   [`crate::field::ParamLayout`]);
//! - `adam_m.<group>`, `adam_v.<group>`: f32, AdamW's moments, same shapes;
//! - `occupancy.occ`: f32 `[r, r, r]`, `occupancy.binary`: u8 `[r, r, r]`;
//! - with error-map sampling (`train.error_map`), `error_map.err` and `error_map.cdf`: f32
//!   `[n_cells]` ([`super::error_map::ErrorMap`]);
//! - with pose refinement (`train.pose_refine`), `pose.state`: f64 `[views, 18]`, each view's
//!   correction `ω, t` and their Adam moments (metadata `pose_t`: Adam's steps); with the focal
//!   learned too (`train.pose_refine.focal`), `pose.focal`: f64 `[camera models, 3]`, each
//!   model's focal log scale `φ` and its moments; with the gate (`train.pose_refine.gate`),
//!   `pose.gate`: f64 `[views, 14]`, what it heard and decided.
//!
//! Metadata (strings): `format` = `neus-aug-checkpoint-1`, `step` (completed steps), `adam_t`,
//! `num_rays` (the dynamic ray count), `skipped_steps`, `config_hash` (of the resolved run
//! configuration, so a resume with another configuration is refused) and `config` (the TOML).

use super::adam::AdamW;
use super::error_map::{ErrorMap, ErrorMapConfig};
use super::pose_refine::{Gate, PoseState};

/// The tensor of pose refinement's state: `[views][18]` f64 rows `ω, t, m, v`
/// ([`PoseState::to_rows`]).
const POSE_TENSOR: &str = "pose.state";
/// The tensor of the learned focal scales: `[models][3]` f64 rows `φ, m, v`
/// ([`PoseState::focal_rows`]); absent when the focal is not learned.
const FOCAL_TENSOR: &str = "pose.focal";
/// The tensor of pose refinement's gate (`train.pose_refine.gate`): `[views][14]` f64 rows
/// ([`super::pose_refine::Gate::to_rows`]); absent without the gate.
const GATE_TENSOR: &str = "pose.gate";
use crate::field::ParamLayout;
use crate::render::occupancy::OccupancyGrid;
use safetensors::tensor::{Dtype, TensorView};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The format tag written into the metadata.
pub const FORMAT: &str = "neus-aug-checkpoint-1";

/// Errors of checkpoint input/output, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// Reading or writing failed.
    #[error("cannot access checkpoint {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a neus-aug checkpoint or is damaged.
    #[error("{path} is not a valid neus-aug checkpoint: {why}")]
    Invalid { path: PathBuf, why: String },
    /// The checkpoint belongs to another configuration.
    #[error(
        "{path} was written by a run with another configuration (hash {found}, this run {expected}); \
         use a new --out directory or the same configuration"
    )]
    ConfigMismatch {
        path: PathBuf,
        found: String,
        expected: String,
    },
}

/// Everything needed to continue a run exactly where it stopped.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainState {
    /// Completed steps.
    pub step: u64,
    /// Flat parameters (layout of the model).
    pub params: Vec<f32>,
    /// Optimiser state.
    pub adam: AdamW,
    /// Occupancy grid.
    pub occ: OccupancyGrid,
    /// Dynamic ray count for the next step.
    pub num_rays: usize,
    /// Steps skipped by the optimiser's NaN guard so far.
    pub skipped_steps: u64,
    /// The error map of error-map sampling (`None` when `train.error_map` is off).
    pub error_map: Option<ErrorMap>,
    /// Pose refinement's corrections and moments (`None` when `train.pose_refine` is off).
    pub pose: Option<PoseState>,
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_f32(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Writes `state` to `path` atomically ([`dtu_eval::atomic::write_atomic`]).
pub fn save(
    path: &Path,
    state: &TrainState,
    layout: &ParamLayout,
    config_toml: &str,
    config_hash: &str,
) -> Result<(), CheckpointError> {
    let invalid = |why: String| CheckpointError::Invalid {
        path: path.into(),
        why,
    };
    let mut owned: Vec<(String, Vec<usize>, Dtype, Vec<u8>)> = Vec::new();
    for g in &layout.groups {
        let r = g.range();
        for (prefix, buf) in [
            ("params", &state.params),
            ("adam_m", &state.adam.m),
            ("adam_v", &state.adam.v),
        ] {
            owned.push((
                format!("{prefix}.{}", g.name),
                g.shape.clone(),
                Dtype::F32,
                f32_bytes(&buf[r.clone()]),
            ));
        }
    }
    let res = state.occ.resolution;
    owned.push((
        "occupancy.occ".into(),
        vec![res, res, res],
        Dtype::F32,
        f32_bytes(&state.occ.occ),
    ));
    owned.push((
        "occupancy.binary".into(),
        vec![res, res, res],
        Dtype::U8,
        state.occ.binary.iter().map(|&b| b as u8).collect(),
    ));
    if let Some(m) = &state.error_map {
        for (name, v) in [("error_map.err", &m.err), ("error_map.cdf", &m.cdf)] {
            owned.push((name.into(), vec![v.len()], Dtype::F32, f32_bytes(v)));
        }
    }
    if let Some(ps) = &state.pose {
        // f64 rows of `width` values each.
        let mut push_rows = |name: &str, rows: Vec<f64>, width: usize| {
            let bytes = rows.iter().flat_map(|x| x.to_le_bytes()).collect();
            owned.push((
                name.into(),
                vec![rows.len() / width, width],
                Dtype::F64,
                bytes,
            ));
        };
        push_rows(POSE_TENSOR, ps.to_rows(), 18);
        if !ps.focal.is_empty() {
            push_rows(FOCAL_TENSOR, ps.focal_rows(), 3);
        }
        if let Some(g) = &ps.gate {
            push_rows(GATE_TENSOR, g.to_rows(), 14);
        }
    }
    let views: Vec<(String, TensorView)> = owned
        .iter()
        .map(|(name, shape, dtype, bytes)| {
            TensorView::new(*dtype, shape.clone(), bytes)
                .map(|v| (name.clone(), v))
                .map_err(|e| invalid(format!("tensor {name}: {e}")))
        })
        .collect::<Result<_, _>>()?;
    let mut meta: HashMap<String, String> = [
        ("format", FORMAT.to_string()),
        ("step", state.step.to_string()),
        ("adam_t", state.adam.t.to_string()),
        ("num_rays", state.num_rays.to_string()),
        ("skipped_steps", state.skipped_steps.to_string()),
        ("occupancy_radius", state.occ.radius.to_string()),
        ("config_hash", config_hash.to_string()),
        ("config", config_toml.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    if let Some(ps) = &state.pose {
        meta.insert("pose_t".into(), ps.t.to_string());
    }
    let bytes = safetensors::serialize(views, Some(meta)).map_err(|e| invalid(e.to_string()))?;
    dtu_eval::atomic::write_atomic(path, &bytes).map_err(|source| CheckpointError::Io {
        path: path.into(),
        source,
    })
}

/// The metadata of a neus-aug checkpoint (`format`, `config_hash`, `config`, ...), reading only
/// the header; `None` for a missing or foreign file.
pub fn metadata(path: &Path) -> Option<std::collections::HashMap<String, String>> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).ok()?;
    let mut len = [0u8; 8];
    f.read_exact(&mut len).ok()?;
    let n = u64::from_le_bytes(len);
    if n > 100 << 20 {
        return None;
    }
    let mut header = vec![0u8; n as usize];
    f.read_exact(&mut header).ok()?;
    let v: serde_json::Value = serde_json::from_slice(&header).ok()?;
    let meta: std::collections::HashMap<String, String> =
        serde_json::from_value(v.get("__metadata__")?.clone()).ok()?;
    (meta.get("format").map(String::as_str) == Some(FORMAT)).then_some(meta)
}

/// Whether `path` is a neus-aug checkpoint: a safetensors file whose metadata `format` is
/// [`FORMAT`]. Reads only the header; never fails (a missing or foreign file is `false`).
pub fn is_checkpoint(path: &Path) -> bool {
    metadata(path).is_some()
}

/// Checks that every value of tensor `name` is finite (and, for `non_negative`, such as Adam's
/// second moment, not below 0): a damaged optimiser state would otherwise make every remaining
/// step be skipped by the NaN guard while the run still reports success.
fn check_values(name: &str, values: &[f32], non_negative: bool) -> Result<(), String> {
    let bad = |x: f32| !x.is_finite() || (non_negative && x < 0.0);
    match values.iter().position(|&x| bad(x)) {
        None => Ok(()),
        Some(i) => {
            let count = values.iter().filter(|&&x| bad(x)).count();
            let want = if non_negative {
                "finite and ≥ 0"
            } else {
                "finite"
            };
            Err(format!(
                "tensor {name} has {count} value(s) that are not {want} (first: element {i} = {})",
                values[i]
            ))
        }
    }
}

/// Reads a checkpoint written by [`save`] for a model with `layout`, refusing one whose
/// `config_hash` differs from `expected_hash`. `error_map`: the run's error-map settings and
/// training-view sizes when error-map sampling is on (the map is then required and checked
/// against them); `None` ignores any stored map. `pose_views`: the number of training views when
/// pose refinement is on (its state is then required, one row per view); `None` ignores it.
pub fn load(
    path: &Path,
    layout: &ParamLayout,
    adam_config: &super::adam::AdamWConfig,
    expected_hash: &str,
    error_map: Option<(&ErrorMapConfig, &[(u32, u32)])>,
    pose_views: Option<usize>,
) -> Result<TrainState, CheckpointError> {
    let invalid = |why: String| CheckpointError::Invalid {
        path: path.into(),
        why,
    };
    let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io {
        path: path.into(),
        source,
    })?;
    let (_, header) =
        safetensors::SafeTensors::read_metadata(&bytes).map_err(|e| invalid(e.to_string()))?;
    let meta = header
        .metadata()
        .clone()
        .ok_or_else(|| invalid("no metadata".into()))?;
    let get = |k: &str| {
        meta.get(k)
            .cloned()
            .ok_or_else(|| invalid(format!("metadata key '{k}' missing")))
    };
    if get("format")? != FORMAT {
        return Err(invalid(format!("format is not {FORMAT}")));
    }
    let found = get("config_hash")?;
    if found != expected_hash {
        return Err(CheckpointError::ConfigMismatch {
            path: path.into(),
            found,
            expected: expected_hash.into(),
        });
    }
    let num = |k: &str| -> Result<u64, CheckpointError> {
        get(k)?
            .parse()
            .map_err(|_| invalid(format!("metadata '{k}' is not a number")))
    };
    let st = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| invalid(e.to_string()))?;
    let tensor = |name: &str, dtype: Dtype, shape: &[usize]| -> Result<Vec<u8>, CheckpointError> {
        let t = st
            .tensor(name)
            .map_err(|e| invalid(format!("tensor {name}: {e}")))?;
        if t.dtype() != dtype || t.shape() != shape {
            return Err(invalid(format!(
                "tensor {name} is {:?} {:?}, expected {dtype:?} {shape:?}",
                t.dtype(),
                t.shape()
            )));
        }
        Ok(t.data().to_vec())
    };
    let n = layout.total();
    let (mut params, mut m, mut v) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
    for g in &layout.groups {
        let r = g.range();
        for (prefix, buf) in [
            ("params", &mut params),
            ("adam_m", &mut m),
            ("adam_v", &mut v),
        ] {
            let name = format!("{prefix}.{}", g.name);
            let values = bytes_f32(&tensor(&name, Dtype::F32, &g.shape)?);
            check_values(&name, &values, prefix == "adam_v").map_err(invalid)?;
            buf[r.clone()].copy_from_slice(&values);
        }
    }
    let occ_t = st
        .tensor("occupancy.occ")
        .map_err(|e| invalid(format!("tensor occupancy.occ: {e}")))?;
    let res = occ_t.shape().first().copied().unwrap_or(0);
    let radius: f32 = get("occupancy_radius")?
        .parse()
        .map_err(|_| invalid("metadata 'occupancy_radius' is not a number".into()))?;
    if !(radius.is_finite() && radius > 0.0) {
        return Err(invalid(format!(
            "metadata 'occupancy_radius' = {radius} is not a positive number"
        )));
    }
    let mut occ = OccupancyGrid::new(res, radius);
    occ.occ = bytes_f32(&tensor("occupancy.occ", Dtype::F32, &[res, res, res])?);
    check_values("occupancy.occ", &occ.occ, false).map_err(invalid)?;
    occ.binary = tensor("occupancy.binary", Dtype::U8, &[res, res, res])?
        .iter()
        .map(|&b| b != 0)
        .collect();
    let error_map = match error_map {
        None => None,
        Some((cfg, sizes)) => {
            let stored = |name: &str| -> Result<Vec<f32>, CheckpointError> {
                let t = st
                    .tensor(name)
                    .map_err(|e| invalid(format!("tensor {name}: {e}")))?;
                let shape = t.shape().to_vec();
                Ok(bytes_f32(&tensor(name, Dtype::F32, &shape)?))
            };
            let (err, cdf) = (stored("error_map.err")?, stored("error_map.cdf")?);
            Some(
                ErrorMap::restore(cfg, sizes, err, cdf)
                    .map_err(|e| invalid(format!("error map: {e}")))?,
            )
        }
    };
    let pose = match pose_views {
        None => None,
        Some(views) => {
            let f64s = |raw: Vec<u8>| -> Vec<f64> {
                raw.chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                    .collect()
            };
            let rows = f64s(tensor(POSE_TENSOR, Dtype::F64, &[views, 18])?);
            // The focal scales are optional: as many rows as the scene has camera models.
            let focal = match st.tensor(FOCAL_TENSOR).ok().map(|t| t.shape().to_vec()) {
                Some(shape) if shape.len() == 2 => {
                    f64s(tensor(FOCAL_TENSOR, Dtype::F64, &[shape[0], 3])?)
                }
                Some(shape) => return Err(invalid(format!("tensor {FOCAL_TENSOR} is {shape:?}"))),
                None => Vec::new(),
            };
            let mut ps = PoseState::from_rows(&rows, &focal, num("pose_t")?).ok_or_else(|| {
                invalid(format!(
                    "tensor {POSE_TENSOR} or {FOCAL_TENSOR}: a value is not finite"
                ))
            })?;
            if st.tensor(GATE_TENSOR).is_ok() {
                let rows = f64s(tensor(GATE_TENSOR, Dtype::F64, &[views, 14])?);
                ps.gate = Some(Gate::from_rows(&rows, views).ok_or_else(|| {
                    invalid(format!(
                        "tensor {GATE_TENSOR}: a value is not finite or the rows disagree"
                    ))
                })?);
            }
            Some(ps)
        }
    };
    Ok(TrainState {
        step: num("step")?,
        params,
        adam: AdamW {
            config: adam_config.clone(),
            m,
            v,
            t: num("adam_t")?,
        },
        occ,
        num_rays: num("num_rays")? as usize,
        skipped_steps: num("skipped_steps")?,
        error_map,
        pose,
    })
}
