//! Shared helpers of the field/render integration tests: a tiny model and a deterministic batch.
// Each integration test uses a different subset of these helpers.
#![allow(dead_code)]

use neus_aug::field::config::{AppearanceConfig, ColorMlpConfig, HashGridConfig, SdfMlpConfig};
use neus_aug::field::FieldConfig;
use neus_aug::render::{LossConfig, ModelConfig, NeusModel, RayBatch, RenderConfig};
use neus_aug::train::Targets;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Fuzz seed from `NEUS_AUG_TEST_SEED` (default 12345) so failures reproduce.
pub fn seed() -> u64 {
    std::env::var("NEUS_AUG_TEST_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(12345)
}

/// A tiny model: 4 levels (two dense, two hashed), width-16 MLPs (a width the register kernels
/// specialise, so the gradient checks run them), appearance codes with the scalar.
pub fn tiny_config() -> ModelConfig {
    ModelConfig {
        field: FieldConfig {
            hash_grid: HashGridConfig {
                n_levels: 4,
                n_features_per_level: 2,
                log2_hashmap_size: 8,
                base_resolution: 4.0,
                per_level_scale: 1.8,
                ..Default::default()
            },
            sdf: SdfMlpConfig {
                n_neurons: 16,
                n_hidden_layers: 1,
                feature_dim: 5,
                ..Default::default()
            },
            color: ColorMlpConfig {
                n_neurons: 16,
                n_hidden_layers: 2,
            },
            appearance: AppearanceConfig {
                n_codes: 3,
                code_dim: 2,
                with_scalar: true,
            },
        },
        render: RenderConfig {
            num_samples_per_ray: 24,
            chunk_samples: 40,
            shards: 2,
            cos_anneal_end: 100,
            background: [1.0, 0.9, 0.8],
            ..Default::default()
        },
        loss: LossConfig {
            rgb_l1: 1.0.into(),
            rgb_mse: 0.5.into(),
            eikonal: 0.1.into(),
            mask: 0.1.into(),
            ..Default::default()
        },
        background: Default::default(),
    }
}

/// [`tiny_config`] with a small learned background: 6 samples beyond the box, 2
/// frequencies, width-16 networks, 3 features.
pub fn tiny_background_config() -> ModelConfig {
    use neus_aug::render::{BackgroundConfig, BackgroundKind};
    ModelConfig {
        background: BackgroundConfig {
            kind: BackgroundKind::Nerfpp,
            n_outside: 6,
            n_frequencies: 2,
            n_neurons: 16,
            n_hidden_layers: 1,
            color_hidden_layers: 1,
            feature_dim: 3,
        },
        ..tiny_config()
    }
}

/// Initial parameters perturbed so every group has an effect: hash entries `±0.3`, SDF MLP
/// `+U(±0.3)`, appearance
/// `±0.5`, `v = 0.2`.
pub fn perturbed_params(model: &NeusModel, seed: u64) -> Vec<f32> {
    let mut p = model.init_params(seed);
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0xabc);
    let l = &model.layout;
    for i in l.group("hash_grid").unwrap().range() {
        p[i] = rng.random_range(-0.3..0.3);
    }
    // Sphere init zeroes the first layer's grid columns (so the table would get no gradient).
    for i in l.group("sdf_mlp").unwrap().range() {
        p[i] += rng.random_range(-0.3..0.3);
    }
    for i in l.group("appearance").unwrap().range() {
        p[i] = rng.random_range(-0.5..0.5);
    }
    p[l.group("variance").unwrap().offset] = 0.2;
    p
}

/// `n` rays from a sphere of radius 2.5 aimed near the origin, with targets, masks, codes and p.
#[derive(Default)]
pub struct Batch {
    pub origins: Vec<[f32; 3]>,
    pub dirs: Vec<[f32; 3]>,
    pub rgb: Vec<[f32; 3]>,
    pub mask: Vec<f32>,
    pub codes: Vec<u32>,
    pub p: Vec<f32>,
}

pub fn batch(n: usize, seed: u64) -> Batch {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut b = Batch::default();
    for _ in 0..n {
        let mut o = [0f32; 3];
        loop {
            for v in o.iter_mut() {
                *v = rng.random_range(-1.0..1.0);
            }
            let l = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
            if l > 0.1 && l <= 1.0 {
                o = o.map(|v| v * 2.5 / l);
                break;
            }
        }
        let target: [f32; 3] = [
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
        ];
        let d = [target[0] - o[0], target[1] - o[1], target[2] - o[2]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        b.origins.push(o);
        b.dirs.push(d.map(|v| v / l));
        b.rgb.push([rng.random(), rng.random(), rng.random()]);
        b.mask.push(if rng.random::<bool>() { 1.0 } else { 0.0 });
        b.codes.push(rng.random_range(0..3));
        b.p.push(rng.random_range(-0.5..0.5));
    }
    b
}

impl Batch {
    /// The rays of the batch, borrowed in the model's layout.
    pub fn rays(&self) -> RayBatch<'_> {
        RayBatch {
            origins: &self.origins,
            dirs: &self.dirs,
            codes: &self.codes,
            p: &self.p,
        }
    }

    /// The batch's colours with its mask as targets.
    pub fn targets(&self) -> Targets<'_> {
        Targets {
            rgb: &self.rgb,
            mask: Some(&self.mask),
        }
    }
}
