//! The tiny scene and configuration the end-to-end tests train on: 8 views at 48×36 of the
//! built-in `blob` with coarse ground truth, and a few dozen steps of a tiny network.

use neus_aug::sim;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The tiny scene, generated once per test process into a temporary folder.
pub fn scene() -> &'static Path {
    static SCENE: OnceLock<PathBuf> = OnceLock::new();
    SCENE.get_or_init(|| {
        let mut desc = sim::builtin("blob").unwrap();
        desc.rig.views = 8;
        desc.rig.resolution = [48, 36];
        desc.render.spp = 1;
        desc.gt.spacing_mm = 1.0;
        desc.gt.obs_res_mm = 4.0;
        let root = tempfile::tempdir().unwrap().keep();
        let dir = root.join("tiny");
        sim::generate(&desc, &dir, &Default::default()).unwrap();
        dir
    })
}

/// A configuration of `iterations` steps of a tiny network (checkpoint every 4 steps, learning
/// rate constant for the first half, a 32³ mesh, the visual-hull start on a 24³ grid wherever the
/// run has masks), followed by `extra` TOML.
pub fn config(iterations: u64, extra: &str) -> String {
    format!(
        r#"
preset = "fast"
[data]
holdout = 1
render_downscale = 2
[train]
iterations = {iterations}
checkpoint_every = 4
[train.lr]
warmup_steps = 0
constant_steps = {half}
[train.init]
kind = "auto"
resolution = 24
steps = 40
points = 1024
[model.field.hash_grid]
n_levels = 6
log2_hashmap_size = 12
base_resolution = 8.0
per_level_scale = 1.5
[model.render]
num_samples_per_ray = 64
train_num_rays = 64
max_train_num_rays = 256
shards = 2
cos_anneal_end = {iterations}
[model.render.occupancy]
resolution = 16
[mesh]
coarse_res = 24
fine_res = 32
{extra}
"#,
        half = iterations / 2
    )
}

/// Writes [`config`] to `dir/tiny.toml` and returns its path.
pub fn write_config(dir: &Path, iterations: u64, extra: &str) -> PathBuf {
    let p = dir.join("tiny.toml");
    std::fs::write(&p, config(iterations, extra)).unwrap();
    p
}

/// The `neus-aug` binary with two rayon threads (results do not depend on it; speed does).
pub fn neus_aug() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_neus-aug"));
    c.env("RAYON_NUM_THREADS", "2");
    c
}
