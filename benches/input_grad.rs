//! `cargo bench --bench input_grad`: the hash encoding's gradient with respect to the input
//! position at a sample and its six finite-difference taps (pose refinement's hot loop, see
//! `render::step::rays`), the stencil path (`HashGrid::encode_fd_input_vjp`) against its peer,
//! the per-point reference (`HashGrid::encode_input_vjp` seven times), measured in the same run,
//! interleaved, one thread, best of the rounds. A few seconds.
//!
//! Inputs: the default grid (L = 16, F = 2, T = 2^19, finest level 2048), every level active,
//! a table of random values, 16 384 samples uniform in the unit cube's inner part with taps at
//! ±one cell of the finest level (the training's `ε`), random `d_out` rows. Prints µs per sample
//! for both and their ratio; both results are summed so neither is optimised away, and the sums
//! are checked to agree.
//!
//! `NEUS_AUG_ROUNDS` (default 7) sets the rounds.

use neus_aug::field::config::HashGridConfig;
use neus_aug::field::hashgrid::{fd_point, HashGrid};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use std::hint::black_box;
use std::time::Instant;

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}

fn main() {
    let g = HashGrid::new(&HashGridConfig::default());
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    let table: Vec<f32> = (0..g.n_params())
        .map(|_| rng.random_range(-1e-2..1e-2))
        .collect();
    let d = g.output_dim();
    let active = g.levels.len();
    let eps = 2.0 / g.levels.last().map_or(2048.0, |l| l.scale) as f32;
    let n = 16_384;
    let xs: Vec<[f32; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.9f32..0.9)))
        .collect();
    let taps: Vec<[[f32; 2]; 3]> = xs
        .iter()
        .map(|x| std::array::from_fn(|a| [x[a] + eps, x[a] - eps]))
        .collect();
    let d_out: Vec<f32> = (0..n * 7 * d)
        .map(|_| rng.random_range(-1.0f32..1.0))
        .collect();
    let rounds: usize = std::env::var("NEUS_AUG_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);
    let skip = [false; 7];
    let (mut best_ref, mut best_fast) = (f64::MAX, f64::MAX);
    let (mut sum_ref, mut sum_fast) = (0f64, 0f64);
    for _ in 0..rounds {
        let t = Instant::now();
        let mut s = 0f64;
        for i in 0..n {
            let rows: [usize; 7] = std::array::from_fn(|p| (7 * i + p) * d);
            for (p, &row) in rows.iter().enumerate() {
                let pt = fd_point(xs[i], taps[i], p);
                let v = g.encode_input_vjp(&table, pt, 1.0, active, &d_out[row..row + d]);
                s += f64::from(v[0] + v[1] + v[2]);
            }
        }
        best_ref = best_ref.min(t.elapsed().as_secs_f64());
        sum_ref = black_box(s);
        let t = Instant::now();
        let mut s = 0f64;
        for i in 0..n {
            let rows: [usize; 7] = std::array::from_fn(|p| (7 * i + p) * d);
            let v =
                g.encode_fd_input_vjp(&table, xs[i], taps[i], 1.0, active, &d_out, &rows, &skip);
            s += v.iter().map(|r| f64::from(r[0] + r[1] + r[2])).sum::<f64>();
        }
        best_fast = best_fast.min(t.elapsed().as_secs_f64());
        sum_fast = black_box(s);
    }
    let agree = (sum_ref - sum_fast).abs() <= 1e-3 * (1.0 + sum_ref.abs());
    println!("hash encoding's input gradient, 7 points per sample, one thread, {n} samples, best of {rounds} rounds");
    println!("  CPU: {}", cpu_model());
    println!(
        "  per-point reference {:.2} us/sample, stencil {:.2} us/sample: stencil {:.2}x faster",
        1e6 * best_ref / n as f64,
        1e6 * best_fast / n as f64,
        best_ref / best_fast
    );
    println!("  sums agree: {agree} ({sum_ref:.6e} vs {sum_fast:.6e})");
    assert!(agree, "the two paths disagree");
}
