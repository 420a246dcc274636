//! One whole training iteration (ray batch + augmentation + forward/backward + AdamW) for the
//! baseline, SIA and DIA, on the embedded default scene with the `fast` preset's network. The
//! paper measured DIA at ~3× the baseline on a GPU because it manipulates whole images; here DIA
//! manipulates only the sampled pixels, so the target is DIA ≤ 1.1× and SIA ≤ 1.02× the baseline.
//!
//! Run: `cargo bench --bench iteration` (about a minute; generates the default scene into the
//! cache on first use). Each arm starts from its own seeded state, warms up, then the arms are
//! interleaved step by step with a fixed ray count (no dynamic ray count, so every arm does the
//! same work per step); figures are medians over the steps that did not update the occupancy grid. Environment: `NEUS_AUG_BENCH_STEPS`
//! (timed steps per arm, default 30), `NEUS_AUG_BENCH_RAYS` (rays per step, default 1024),
//! `NEUS_AUG_BENCH_WARMUP` (untimed steps per arm first, default 24).

use neus_aug::augment::{AugMode, AugSampler};
use neus_aug::reconstruct::{parse_set, resolve, Preset};
use neus_aug::render::model::NeusModel;
use neus_aug::scene::{LoadOptions, Scene};
use neus_aug::sim;
use neus_aug::train::{TrainConfig, TrainData, TrainState, Trainer};
use std::time::Instant;

// The same allocator as the `neus-aug` binary, so the timings are the program's.
#[global_allocator]
static ALLOC: neus_aug::field::alloc::LargeAligned = neus_aug::field::alloc::LargeAligned;

fn env(key: &str, default: usize) -> usize {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

struct Arm {
    name: &'static str,
    model: NeusModel,
    data: TrainData,
    train: TrainConfig,
    seed: u64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn main() {
    let steps = env("NEUS_AUG_BENCH_STEPS", 30);
    let rays = env("NEUS_AUG_BENCH_RAYS", 1024);
    let dir = sim::ensure_builtin("default", &sim::default_cache_root().unwrap()).unwrap();
    let scene = Scene::load(&dir, &LoadOptions::default()).unwrap();
    println!(
        "scene {} ({} views, {}×{}), {} rays/step, {} timed steps per arm, {} threads",
        dir.display(),
        scene.views.len(),
        scene.views[0].image.width,
        scene.views[0].image.height,
        rays,
        steps,
        rayon::current_num_threads()
    );
    let arms: Vec<Arm> = [
        ("baseline", AugMode::None),
        ("SIA", AugMode::Sia),
        ("DIA", AugMode::Dia),
    ]
    .into_iter()
    .map(|(name, mode)| {
        let sets = vec![
            parse_set(&format!("augment.mode={}", mode.name())).unwrap(),
            parse_set(&format!("model.render.train_num_rays={rays}")).unwrap(),
            parse_set(&format!("model.render.max_train_num_rays={rays}")).unwrap(),
        ];
        let cfg = resolve(Some(Preset::Fast), None, &sets).unwrap();
        let t = Instant::now();
        let sampler = AugSampler::new(
            scene.views.iter().map(|v| v.image.clone()).collect(),
            &cfg.augment,
        )
        .unwrap();
        let setup = t.elapsed().as_secs_f64();
        let masks = scene.views.iter().map(|v| v.mask.clone()).collect();
        let cams: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
        let data = TrainData::new(&cams, sampler, masks, cfg.model.render.background).unwrap();
        println!(
            "{name:>8}: colour-network input {} (appearance {}×{}{}), sampler set-up {:.3} s",
            cfg.model.field.appearance.code_dim
                * usize::from(cfg.model.field.appearance.n_codes > 0)
                + usize::from(cfg.model.field.appearance.with_scalar)
                + 32,
            cfg.model.field.appearance.n_codes,
            cfg.model.field.appearance.code_dim,
            if cfg.model.field.appearance.with_scalar {
                " + p"
            } else {
                ""
            },
            setup
        );
        Arm {
            name,
            model: NeusModel::new(cfg.model.clone()).unwrap(),
            data,
            train: cfg.train.clone(),
            seed: cfg.seed,
        }
    })
    .collect();

    // A short warm-up per arm; steps that update the occupancy grid (the same work in every arm)
    // are left out of the timings.
    let warm = env("NEUS_AUG_BENCH_WARMUP", 24) as u64;
    let mut trainers: Vec<Trainer> = arms
        .iter()
        .map(|a| Trainer::new(&a.model, &a.data, &a.train, a.seed, 0))
        .collect();
    let mut states: Vec<TrainState> = trainers
        .iter_mut()
        .map(|tr| {
            let mut s = tr.initial_state();
            while s.step < warm {
                s.num_rays = rays;
                tr.step(&mut s).unwrap();
            }
            s
        })
        .collect();
    let mut times = vec![Vec::new(); arms.len()];
    let mut samples = vec![0usize; arms.len()];
    while times[0].len() < steps {
        for (i, (tr, state)) in trainers.iter_mut().zip(states.iter_mut()).enumerate() {
            state.num_rays = rays;
            let t = Instant::now();
            let r = tr.step(state).unwrap();
            if !r.occupancy_updated {
                times[i].push(t.elapsed().as_secs_f64());
                samples[i] += r.out.n_samples;
            }
        }
    }
    let base = median(times[0].clone());
    println!(
        "\n{:>8} {:>14} {:>16} {:>12}",
        "arm", "ms/iteration", "samples/iter", "× baseline"
    );
    for (i, a) in arms.iter().enumerate() {
        let m = median(times[i].clone());
        println!(
            "{:>8} {:>14.2} {:>16} {:>12.3}",
            a.name,
            m * 1e3,
            samples[i] / times[i].len().max(1),
            m / base
        );
    }
    println!("targets: SIA ≤ 1.02×, DIA ≤ 1.1× (the paper: DIA ~3× on a GPU)");
}
