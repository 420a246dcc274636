//! Pixel-level cost of the augmentations: fetching a batch of training pixels plain, through the
//! sampler with `none`, with SIA's precomputed replicas and with DIA's per-pixel manipulation.
//! (The whole-iteration benchmark, where this cost is set against the network's, comes with the
//! training loop.) Also shown: SIA's one-off replica cost and memory, and what manipulating one
//! whole view costs, i.e. the alternative to per-pixel DIA.
//!
//! Run: `cargo bench -p neus-aug --bench augment` (about 20 s). Inputs are built outside the timed
//! regions; methods are interleaved round by round and each figure is the median over rounds.

use neus_aug::augment::{AugMode, AugSample, AugSampler, AugmentConfig, Manipulation, PixelRef};
use neus_aug::scene::image::RgbImage;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use std::hint::black_box;
use std::time::Instant;

const N_VIEWS: usize = 32;
const WIDTH: usize = 400;
const HEIGHT: usize = 300;
const BATCH: usize = 8192;
const N_BATCHES: usize = 32;
const ROUNDS: usize = 15;

fn views(seed: u64) -> Vec<RgbImage> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    (0..N_VIEWS)
        .map(|v| {
            RgbImage::from_fn(WIDTH, HEIGHT, |x, y| {
                let t = (x as f32 * 0.05 + y as f32 * 0.03 + v as f32).sin() * 0.3 + 0.5;
                [t, 1.0 - t, rng.random::<f32>() * 0.2 + 0.4]
            })
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn main() {
    let imgs = views(1);
    let mut rng = Pcg64Mcg::seed_from_u64(2);
    let batches: Vec<Vec<PixelRef>> = (0..N_BATCHES)
        .map(|_| {
            (0..BATCH)
                .map(|_| PixelRef {
                    view: rng.random_range(0..N_VIEWS as u32),
                    x: rng.random_range(0..WIDTH as u32),
                    y: rng.random_range(0..HEIGHT as u32),
                })
                .collect()
        })
        .collect();

    let cfg = |mode| AugmentConfig {
        mode,
        ..Default::default()
    };
    let none = AugSampler::new(imgs.clone(), &cfg(AugMode::None)).unwrap();
    let dia = AugSampler::new(imgs.clone(), &cfg(AugMode::Dia)).unwrap();
    let t = Instant::now();
    let sia = AugSampler::new(imgs.clone(), &cfg(AugMode::Sia)).unwrap();
    let sia_build = t.elapsed().as_secs_f64();

    // Plain: the baseline's gather, straight from the images.
    let plain = |out: &mut Vec<[f32; 3]>| {
        for b in &batches {
            out.clear();
            out.extend(
                b.iter()
                    .map(|p| imgs[p.view as usize].get(p.x as usize, p.y as usize)),
            );
            black_box(&out);
        }
    };
    let through = |s: &AugSampler, rng: &mut Pcg64Mcg, out: &mut Vec<AugSample>| {
        for b in &batches {
            s.sample_batch(rng, b, out);
            black_box(&out);
        }
    };

    let mut out_plain = Vec::with_capacity(BATCH);
    let mut out = Vec::with_capacity(BATCH);
    let mut aug_rng = Pcg64Mcg::seed_from_u64(3);
    let names = ["plain gather", "sampler none", "SIA", "DIA"];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    // Warm-up round, then timed rounds.
    for round in 0..=ROUNDS {
        for (k, t) in times.iter_mut().enumerate() {
            let start = Instant::now();
            match k {
                0 => plain(&mut out_plain),
                1 => through(&none, &mut aug_rng, &mut out),
                2 => through(&sia, &mut aug_rng, &mut out),
                _ => through(&dia, &mut aug_rng, &mut out),
            }
            if round > 0 {
                t.push(start.elapsed().as_secs_f64() / N_BATCHES as f64);
            }
        }
    }
    let med: Vec<f64> = times.into_iter().map(median).collect();

    // The alternative to per-pixel DIA: manipulating whole views (one per manipulation kind).
    let mut whole = Vec::new();
    for m in Manipulation::NON_IDENTITY {
        let mut t = Vec::new();
        for img in imgs.iter().take(5) {
            let start = Instant::now();
            black_box(m.apply(img, 0.3));
            t.push(start.elapsed().as_secs_f64());
        }
        whole.push((m, median(t)));
    }

    println!(
        "augment bench: {N_VIEWS} views of {WIDTH}x{HEIGHT}, batches of {BATCH} random pixels \
         (median of {ROUNDS} rounds x {N_BATCHES} batches)"
    );
    for (name, t) in names.iter().zip(&med) {
        println!(
            "  {name:<13} {:>9.1} us/batch  {:>6.2} ns/pixel  {:>5.2}x plain  {:>5.2}x none",
            t * 1e6,
            t * 1e9 / BATCH as f64,
            t / med[0],
            t / med[1]
        );
    }
    let mib = |b: usize| b as f64 / (1024.0 * 1024.0);
    println!(
        "  SIA replicas: built once in {:.1} ms; image memory {:.0} MiB vs {:.0} MiB (none/DIA)",
        sia_build * 1e3,
        mib(sia.image_bytes()),
        mib(dia.image_bytes())
    );
    for (m, t) in whole {
        println!(
            "  whole-view {m:<10} {:>7.2} ms per {WIDTH}x{HEIGHT} view = {:>6.1}x one DIA batch",
            t * 1e3,
            t / med[3]
        );
    }
}
