//! `cargo bench --bench field`: throughput of the NeuS training step on the CPU.
//!
//! Prints (all inputs built outside the timed regions):
//! 1. the machine's f32 FMA peak, measured with a tight FMA loop on every rayon thread;
//! 2. the MLP GEMMs through `matrixmultiply` against the naive triple loop (the peer);
//! 3. the training step (forward + backward with 6-tap finite-difference normals) of the default
//!    network: samples/s, time per phase, MLP GFLOP/s and the fraction of the FMA peak;
//! 4. inference rendering throughput for comparison.
//!
//! `NEUS_AUG_BENCH_SECS` (default 8) sets the seconds spent on the training-step measurement.

use neus_aug::field::mlp::{linear_forward, linear_forward_naive};
use neus_aug::render::{ModelConfig, NeusModel, PhaseTimes, RayBatch, Targets};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

/// GFLOP/s of independent FMA chains on one thread (16 accumulators hide the FMA latency).
fn fma_thread(iters: u64) -> f64 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    unsafe {
        use std::arch::x86_64::*;
        let mut acc = [_mm512_set1_ps(0.0); 16];
        let a = _mm512_set1_ps(0.999_999);
        let b = _mm512_set1_ps(1e-7);
        for _ in 0..iters {
            for v in acc.iter_mut() {
                *v = _mm512_fmadd_ps(*v, a, b);
            }
        }
        let mut s = 0.0;
        for v in acc {
            s += _mm512_reduce_add_ps(v);
        }
        black_box(s);
        return (iters * 16 * 16 * 2) as f64;
    }
    #[allow(unreachable_code)]
    {
        let mut acc = [[0f32; 8]; 16];
        for _ in 0..iters {
            for v in acc.iter_mut() {
                for x in v.iter_mut() {
                    *x = x.mul_add(0.999_999, 1e-7);
                }
            }
        }
        black_box(acc);
        (iters * 16 * 8 * 2) as f64
    }
}

fn fma_peak() -> f64 {
    let threads = rayon::current_num_threads();
    let iters = 50_000_000u64;
    fma_thread(iters / 100); // warm up
    let t = Instant::now();
    let flops: f64 = (0..threads)
        .into_par_iter()
        .map(|_| fma_thread(iters))
        .sum();
    flops / t.elapsed().as_secs_f64()
}

fn gemm_compare() {
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    println!("\n== MLP layers: matrixmultiply vs naive loops (one thread, f32) ==");
    for &(n, di, d_o) in &[
        (14336usize, 35usize, 64usize),
        (2048, 64, 13),
        (2048, 64, 64),
        (2048, 51, 64),
    ] {
        let w: Vec<f32> = (0..di * d_o).map(|_| rng.random_range(-1.0..1.0)).collect();
        let b: Vec<f32> = (0..d_o).map(|_| rng.random_range(-1.0..1.0)).collect();
        let x: Vec<f32> = (0..n * di).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut y = vec![0f32; n * d_o];
        let flops = 2.0 * (n * di * d_o) as f64;
        let reps = (2e9 / flops).ceil() as usize;
        let t = Instant::now();
        for _ in 0..reps {
            linear_forward(&w, &b, &x, n, di, d_o, &mut y);
            black_box(&y);
        }
        let g_mm = flops * reps as f64 / t.elapsed().as_secs_f64() / 1e9;
        let t = Instant::now();
        for _ in 0..reps.div_ceil(4) {
            linear_forward_naive(&w, &b, &x, n, di, d_o, &mut y);
            black_box(&y);
        }
        let g_nv = flops * reps.div_ceil(4) as f64 / t.elapsed().as_secs_f64() / 1e9;
        println!(
            "  [{n} x {di}] -> {d_o}: matrixmultiply {g_mm:6.1} GFLOP/s, naive {g_nv:6.1} GFLOP/s, ratio {:.2}x",
            g_mm / g_nv
        );
    }
}

/// MLP multiply-adds per sample, forward only: SDF hidden layers on 7 points, SDF output layer
/// (13 channels at the centre, 1 at each tap), colour MLP.
fn mlp_macs_per_sample(model: &NeusModel) -> f64 {
    let s = &model.sdf_mlp.dims;
    let mut sdf = 0.0;
    for l in 0..s.len() - 2 {
        sdf += 7.0 * (s[l] * s[l + 1]) as f64;
    }
    let wh = s[s.len() - 2] as f64;
    sdf += wh * *s.last().unwrap() as f64 + 6.0 * wh;
    let c = &model.color_mlp.dims;
    let col: f64 = (0..c.len() - 1).map(|l| (c[l] * c[l + 1]) as f64).sum();
    sdf + col
}

/// Origins, directions, target colours, masks.
type Rays = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<f32>);

fn rays_towards_sphere(n: usize, seed: u64) -> Rays {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let (mut o, mut d, mut c, mut m) = (vec![], vec![], vec![], vec![]);
    for _ in 0..n {
        // Camera positions on a cap at distance 2.5 looking at points in the inner region.
        let th: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let z: f32 = rng.random_range(0.2..0.9);
        let r = (1.0 - z * z).sqrt();
        let orig = [2.5 * r * th.cos(), 2.5 * r * th.sin(), -2.5 * z];
        let tgt: [f32; 3] = [
            rng.random_range(-0.6..0.6),
            rng.random_range(-0.6..0.6),
            rng.random_range(-0.6..0.6),
        ];
        let dir = [tgt[0] - orig[0], tgt[1] - orig[1], tgt[2] - orig[2]];
        let l = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        o.push(orig);
        d.push(dir.map(|v| v / l));
        c.push([rng.random(), rng.random(), rng.random()]);
        m.push(if rng.random::<bool>() { 1.0 } else { 0.0 });
    }
    (o, d, c, m)
}

fn main() {
    let secs: f64 = std::env::var("NEUS_AUG_BENCH_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8.0);
    let threads = rayon::current_num_threads();
    println!("neus-aug field bench: {threads} rayon threads");
    let peak = fma_peak();
    println!(
        "== f32 FMA peak ({threads} threads): {:.1} GFLOP/s ==",
        peak / 1e9
    );
    gemm_compare();

    // Default network (DESIGN §5), sphere init, occupancy grid after the first update.
    let model = NeusModel::new(ModelConfig::default()).expect("default config");
    let mut params = model.init_params(0);
    // Give the grid columns of the first layer some weight so the hash grid matters.
    let sdf = model.layout.group("sdf_mlp").unwrap().clone();
    let mut rng = Pcg64Mcg::seed_from_u64(9);
    for v in &mut params[sdf.range()] {
        *v += rng.random_range(-0.01..0.01);
    }
    let mut occ = model.new_occupancy_grid();
    let t = Instant::now();
    model.update_occupancy(&params, &mut occ, 0, model.config.schedule(0), 0);
    let occ_time = t.elapsed().as_secs_f64();
    println!(
        "\n== occupancy update (all {} cells): {:.2} s, occupied {:.1}% ==",
        occ.n_cells(),
        occ_time,
        100.0 * occ.occupied_fraction()
    );

    let n_rays = 512;
    let (o, d, c, m) = rays_towards_sphere(n_rays, 3);
    let rays = RayBatch {
        origins: &o,
        dirs: &d,
        codes: &[],
        p: &[],
    };
    let targets = Targets {
        rgb: &c,
        mask: Some(&m),
    };
    let sched = model.config.schedule(1000);
    let mut grads = vec![0f32; params.len()];
    // Warm-up step (allocations, page faults of the gradient buffers).
    let w = model
        .train_step(&params, &mut grads, &rays, &targets, sched, Some(&occ), 0)
        .unwrap();
    println!(
        "\n== training step, default network (L=16, F=2, T=2^19, 64-wide), {n_rays} rays, {} samples/step ==",
        w.n_samples
    );
    let mut total = PhaseTimes::default();
    let mut samples = 0usize;
    let mut steps = 0usize;
    let t = Instant::now();
    while t.elapsed().as_secs_f64() < secs || steps < 2 {
        let out = model
            .train_step(
                &params,
                &mut grads,
                &rays,
                &targets,
                sched,
                Some(&occ),
                steps as u64,
            )
            .unwrap();
        samples += out.n_samples;
        steps += 1;
        let tt = out.times;
        total.sample += tt.sample;
        total.encode_fwd += tt.encode_fwd;
        total.sdf_mlp_fwd += tt.sdf_mlp_fwd;
        total.color_fwd += tt.color_fwd;
        total.render += tt.render;
        total.color_bwd += tt.color_bwd;
        total.sdf_mlp_bwd += tt.sdf_mlp_bwd;
        total.encode_bwd += tt.encode_bwd;
        total.reduce += tt.reduce;
    }
    let wall = t.elapsed().as_secs_f64();
    let sps = samples as f64 / wall;
    let macs = mlp_macs_per_sample(&model);
    // Forward + backward of a GEMM layer: 3 products (y, dW, dX) of 2 FLOPs per MAC.
    let flops = sps * macs * 2.0 * 3.0;
    println!(
        "  {steps} steps in {wall:.2} s: {:.0} samples/s ({:.1} ms/step)",
        sps,
        1e3 * wall / steps as f64
    );
    println!(
        "  target 400k samples/s: {:.1}% of target",
        100.0 * sps / 4e5
    );
    println!(
        "  MLP work: {:.0} MACs/sample fwd -> {:.1} GFLOP/s fwd+bwd = {:.1}% of the FMA peak",
        macs,
        flops / 1e9,
        100.0 * flops / peak
    );
    let cpu = total.encode_fwd
        + total.sdf_mlp_fwd
        + total.color_fwd
        + total.render
        + total.color_bwd
        + total.sdf_mlp_bwd
        + total.encode_bwd;
    println!("  where the time goes (CPU seconds summed over shards; wall = {wall:.2} s x {threads} threads):");
    for (name, v) in [
        ("hash encode fwd (7 pts)", total.encode_fwd),
        ("SDF MLP fwd", total.sdf_mlp_fwd),
        ("normals + colour MLP fwd", total.color_fwd),
        ("alpha + compositing + loss", total.render),
        ("colour MLP bwd", total.color_bwd),
        ("normal/eikonal + SDF MLP bwd", total.sdf_mlp_bwd),
        ("hash encode bwd (scatter)", total.encode_bwd),
    ] {
        println!("    {name:<30} {:7.3} s  {:5.1}%", v, 100.0 * v / cpu);
    }
    println!("    {:<30} {:7.3} s (serial)", "ray marching", total.sample);
    println!(
        "    {:<30} {:7.3} s (shard-gradient reduction)",
        "reduce", total.reduce
    );

    // Inference rendering for comparison (no backward).
    let isched = model.config.inference_schedule(1000);
    let r = model.render(&params, &rays, isched, Some(&occ)).unwrap();
    let t = Instant::now();
    let mut k = 0;
    while t.elapsed().as_secs_f64() < secs / 4.0 || k < 2 {
        black_box(model.render(&params, &rays, isched, Some(&occ)).unwrap());
        k += 1;
    }
    let rs = (r.n_samples * k) as f64 / t.elapsed().as_secs_f64();
    println!(
        "\n== render (forward only, FD normals) ==\n  {:.0} samples/s, {:.2}x the training step",
        rs,
        rs / sps
    );
    // SDF queries (marching cubes).
    let pts: Vec<[f32; 3]> = (0..1 << 18)
        .map(|_| {
            [
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ]
        })
        .collect();
    let t = Instant::now();
    black_box(model.sdf(&params, &pts, 16));
    println!(
        "== sdf queries: {:.0} points/s ==",
        pts.len() as f64 / t.elapsed().as_secs_f64()
    );
}
