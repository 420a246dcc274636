//! `cargo bench --bench field`: throughput of the NeuS field on the CPU (about 40 s on an idle
//! 2-core machine, up to twice that on a loaded one).
//!
//! Prints (all inputs built outside the timed regions):
//! 0. the machine: CPU model, the ISA features this build uses (compile time) and those the CPU
//!    has (run time), and a STREAM-like triad bandwidth (`a = b + s·c`, 3 × 128 MB, all threads);
//! 1. the machine's f32 FMA peak (the widest FMA chains the build has: AVX-512, AVX2+FMA or
//!    portable `mul_add`, on every rayon thread, best of 3);
//! 2. the MLP products: every kernel of `field::dense` (the build's marked `*`) against
//!    `matrixmultiply` and the naive triple loop (the peers measured in the same run), with the
//!    build's kernel over `matrixmultiply` per shape, and the SDF hidden layer's parts. The crate
//!    picks its kernel at run time (the header names it): an `x86-64-v3` build on an AVX-512 CPU
//!    meets its AVX-512 kernel, not the one AVX2 CPUs run, unless built with
//!    `MMTEST_FEATURE=avx,avx2,fma` (see `matrixmultiply_kernel`);
//! 3. SDF queries: the occupancy grid's warm-up update (all 128³ cells);
//! 4. the whole training iteration as the training loop runs it, on a realistic batch: rays from
//!    49 cameras around the unit sphere through a sphere SDF of radius 0.5, the occupancy grid
//!    after its first update, the dynamic ray count at the reference sample budget (256 rays ×
//!    1024 samples per ray): `train_step` (forward + backward with 6-tap finite-difference
//!    normals), then `AdamW::step_and_zero_grads` over all parameters. Samples/s for `train_step`
//!    alone and for the whole iteration, the time per phase, the MLP GFLOP/s and the fraction of
//!    the FMA peak, an estimate of the hash-grid memory traffic; then the same iteration with the
//!    recipe's curvature loss on, and with one-sided differences (`render.fd_central_every = 4`,
//!    opt-in) before and during the curvature ramp, each against its central-difference peer;
//! 5. the hash-grid paths alone (general / per-level stencil / level-parallel batch), one thread;
//! 6. the training iteration with smaller hash tables (T = 2^17, 2^16) as CPU presets may use;
//! 7. rendering (forward only) and SDF queries at random points.
//!
//! The machine may be shared: every throughput is printed per wall-clock second and per CPU
//! second of this process times the thread count, with the load average and the share of the
//! cores the process got. Trust the wall-clock figure when that share is above ~90%; under
//! contention the CPU-time figure overestimates (other processes also slow the memory system).
//!
//! `NEUS_AUG_BENCH_SECS` (default 6) sets the seconds of the main measurement;
//! `NEUS_AUG_BENCH_QUICK=1` runs only the FMA peak and the default network's iteration;
//! `NEUS_AUG_BENCH_MLP_ONLY=1` stops after the MLP products and the SDF layer's parts (0–2);
//! `NEUS_AUG_CHUNK` overrides `chunk_samples`, `NEUS_AUG_BENCH_FD_EVERY` the main measurement's
//! `render.fd_central_every`, `NEUS_AUG_BENCH_FD_SPAN` its and the one-sided pairs'
//! `render.fd_one_sided_span` (default: the `fast` preset's, 2: taps two cells out); both apply to
//! `NEUS_AUG_BENCH_STEP_ONLY`. Profiling aids (callgrind, no AVX-512 there: build
//! with `RUSTFLAGS="-C target-cpu=x86-64-v3"`): `NEUS_AUG_BENCH_HASH_ONLY=<log2 T>` runs only the
//! hash-grid paths, `NEUS_AUG_BENCH_STEP_ONLY=1` two small training steps.

/// Cache-line aligned large buffers on huge pages, as the binary should use (see
/// `neus_aug::field::alloc`).
#[global_allocator]
static ALLOC: neus_aug::field::alloc::LargeAligned = neus_aug::field::alloc::LargeAligned;

use neus_aug::field::hashgrid::{stencil_rows, Sides};
use neus_aug::render::rays::march_rays;
use neus_aug::render::{ModelConfig, NeusModel, OccupancyGrid, PhaseTimes, RayBatch};
use neus_aug::train::trainer::next_num_rays;
use neus_aug::train::{AdamW, AdamWConfig, Targets, TrainStep};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use std::hint::black_box;
use std::time::Instant;

#[path = "field/machine.rs"]
mod machine;
use machine::{fma_peak, l3_cache, loadavg, machine, rate, triad_bandwidth, Clock};

#[path = "field/mlp.rs"]
mod mlp;
use mlp::{gemm_compare, sdf_layer_parts};

/// Points per sample the step evaluates (centre and taps): 7 with central differences; with
/// `render.fd_central_every = k > 1`, 4 (three one-sided taps) while the curvature loss is off
/// and `(7 + 4(k − 1))/k` on average while it is on (every `k`-th sample central).
fn points_per_sample(model: &NeusModel) -> f64 {
    let k = model.config.render.fd_central_every.max(1) as f64;
    if k == 1.0 {
        7.0
    } else if model.config.loss.curvature.at(0) > 0.0 {
        (7.0 + 4.0 * (k - 1.0)) / k
    } else {
        4.0
    }
}

/// MLP multiply-adds per sample, forward and backward as `train_step` computes them: SDF hidden
/// layers on every point ([`points_per_sample`]), SDF output layer (all channels at the centre,
/// the SDF at each tap), colour MLP; backward = weight gradient + input gradient of every layer
/// (the colour input layer and the SDF input layer need their input gradient for the normals and
/// the hash grid).
fn mlp_macs_per_sample(model: &NeusModel) -> (f64, f64) {
    let s = &model.sdf_mlp.dims;
    let pts = points_per_sample(model);
    let mut fwd = 0.0;
    for l in 0..s.len() - 2 {
        fwd += pts * (s[l] * s[l + 1]) as f64;
    }
    let wh = s[s.len() - 2] as f64;
    fwd += wh * *s.last().unwrap() as f64 + (pts - 1.0) * wh;
    let c = &model.color_mlp.dims;
    fwd += (0..c.len() - 1)
        .map(|l| (c[l] * c[l + 1]) as f64)
        .sum::<f64>();
    (fwd, 2.0 * fwd)
}

/// A batch of rays from pinhole cameras on a sphere of radius 2.5 looking at the origin (field
/// of view ~34°, as DTU's normalised cameras), random pixels; targets: random colours, mask = the
/// ray hits the sphere of radius 0.5.
struct Rays {
    origins: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    rgb: Vec<[f32; 3]>,
    mask: Vec<f32>,
}

fn rays_towards_sphere(n: usize, seed: u64) -> Rays {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let n_cams = 49;
    let cams: Vec<[[f32; 3]; 4]> = (0..n_cams)
        .map(|_| {
            let th: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let z: f32 = rng.random_range(-0.3..0.9);
            let r = (1.0 - z * z).sqrt();
            let c = [2.5 * r * th.cos(), 2.5 * r * th.sin(), 2.5 * z];
            let f = norm([-c[0], -c[1], -c[2]]);
            let right = norm(cross(f, [0.0, 0.0, 1.0]));
            let down = cross(f, right);
            [c, f, right, down]
        })
        .collect();
    let half = (17f32).to_radians().tan();
    let mut b = Rays {
        origins: vec![],
        dirs: vec![],
        rgb: vec![],
        mask: vec![],
    };
    for _ in 0..n {
        let [c, f, right, down] = cams[rng.random_range(0..n_cams)];
        let (u, v): (f32, f32) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let d = norm([
            f[0] + half * (u * right[0] + v * down[0]),
            f[1] + half * (u * right[1] + v * down[1]),
            f[2] + half * (u * right[2] + v * down[2]),
        ]);
        // Closest approach to the origin: inside the sphere of radius 0.5 means a hit.
        let tc = -(c[0] * d[0] + c[1] * d[1] + c[2] * d[2]);
        let p = [c[0] + tc * d[0], c[1] + tc * d[1], c[2] + tc * d[2]];
        let hit = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() < 0.5;
        b.origins.push(c);
        b.dirs.push(d);
        b.rgb.push([rng.random(), rng.random(), rng.random()]);
        b.mask.push(if hit { 1.0 } else { 0.0 });
    }
    b
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f32; 3]) -> [f32; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|v| v / l)
}

/// Totals of one measured configuration.
#[derive(Default)]
struct IterStats {
    steps: usize,
    samples: usize,
    rays: usize,
    /// Wall seconds in train_step and in AdamW (zeroing the gradients).
    step: f64,
    adam: f64,
    /// Wall and CPU seconds of the whole loop.
    wall: f64,
    cpu: f64,
    phases: PhaseTimes,
}

fn add_phases(a: &mut PhaseTimes, t: &PhaseTimes) {
    a.sample += t.sample;
    a.encode_fwd += t.encode_fwd;
    a.sdf_mlp_fwd += t.sdf_mlp_fwd;
    a.color_fwd += t.color_fwd;
    a.render += t.render;
    a.color_bwd += t.color_bwd;
    a.sdf_mlp_bwd += t.sdf_mlp_bwd;
    a.encode_bwd += t.encode_bwd;
    a.reduce += t.reduce;
}

/// Sample budget of the reference (`train_num_rays · num_samples_per_ray`).
const BUDGET: usize = 256 * 1024;

/// A model with sphere-initialised parameters (grid columns of the first layer perturbed so the
/// hash grid matters) and its occupancy grid after the first (all-cells) update, timed.
fn setup(cfg: ModelConfig) -> (NeusModel, Vec<f32>, OccupancyGrid, (f64, f64)) {
    let model = NeusModel::new(cfg).expect("valid config");
    let mut params = model.init_params(0);
    let sdf = model.layout.group("sdf_mlp").unwrap().clone();
    let mut rng = Pcg64Mcg::seed_from_u64(9);
    for v in &mut params[sdf.range()] {
        *v += rng.random_range(-0.01..0.01);
    }
    let mut occ = model.new_occupancy_grid();
    let c = Clock::start();
    model.update_occupancy(&params, &mut occ, 0, model.config.schedule(0), 0);
    let t = c.stop();
    (model, params, occ, t)
}

/// Whole training iterations as the training loop runs them, for `secs` seconds: `train_step`
/// on a batch whose ray count follows the dynamic rule towards the sample budget, then
/// `AdamW::step_and_zero_grads` over all parameters.
fn train_iterations(
    model: &NeusModel,
    params: &mut [f32],
    occ: &OccupancyGrid,
    secs: f64,
) -> IterStats {
    let all = rays_towards_sphere(16384, 3);
    let sched = model.config.schedule(1000);
    let mut grads = vec![0f32; params.len()];
    let mut opt = AdamW::new(AdamWConfig::default(), params.len());
    // Start the ray count near its fixed point (samples per ray from marching alone).
    let probe = march_rays(
        &all.origins[..1024],
        &all.dirs[..1024],
        model.config.render.radius,
        model.render_step_size(),
        &[],
        Some(occ),
    );
    let max_rays = model.config.render.max_train_num_rays;
    let mut n_rays = (BUDGET * 1024 / probe.n_samples().max(1)).clamp(1, max_rays);
    let mut offset = 0usize;
    let mut take = |n: usize| {
        let n = n.min(all.origins.len());
        if offset + n > all.origins.len() {
            offset = 0;
        }
        let r = offset..offset + n;
        offset += n;
        r
    };
    let mut st = IterStats::default();
    let mut clock = None;
    let mut k = 0u64;
    // Three warm-up iterations (allocations, page faults, ray count), then the measurement.
    loop {
        if k == 3 {
            clock = Some(Clock::start());
        }
        if let Some(c) = &clock {
            if c.wall.elapsed().as_secs_f64() >= secs && st.steps >= 2 {
                break;
            }
        }
        let r = take(n_rays);
        let rays = RayBatch {
            origins: &all.origins[r.clone()],
            dirs: &all.dirs[r.clone()],
            codes: &[],
            p: &[],
        };
        let t = Targets {
            rgb: &all.rgb[r.clone()],
            mask: Some(&all.mask[r]),
        };
        let t1 = Instant::now();
        let o = model
            .train_step(params, &mut grads, &rays, &t, sched, Some(occ), k)
            .unwrap();
        let t2 = Instant::now();
        opt.step_and_zero_grads(params, &mut grads, &model.layout, 1.0)
            .unwrap();
        let t3 = Instant::now();
        if clock.is_some() {
            st.step += (t2 - t1).as_secs_f64();
            st.adam += (t3 - t2).as_secs_f64();
            st.samples += o.n_samples;
            st.rays += o.n_rays;
            st.steps += 1;
            add_phases(&mut st.phases, &o.times);
        }
        n_rays = next_num_rays(n_rays, o.n_samples, BUDGET, max_rays);
        k += 1;
    }
    (st.wall, st.cpu) = clock.expect("measured").stop();
    st
}

/// Prints an iteration measurement; returns train_step samples/s on idle cores.
fn report(label: &str, model: &NeusModel, st: &IterStats, peak: f64, detail: bool) -> f64 {
    let threads = rayon::current_num_threads() as f64;
    let n = st.samples as f64;
    // CPU share of the loop that the process got, used to normalise wall-clock parts.
    let share = (st.cpu / (st.wall * threads)).min(1.0);
    println!(
        "\n== {label}: {} params, {} iterations of {:.0} rays x {:.0} samples/ray = {:.0} samples ==",
        model.n_params(),
        st.steps,
        st.rays as f64 / st.steps as f64,
        n / st.rays as f64,
        n / st.steps as f64
    );
    println!(
        "  whole iteration (train_step + AdamW, zeroing the grads): {} samples",
        rate(n, st.wall, st.cpu)
    );
    let step_cpu = st.step * threads * share;
    println!(
        "  train_step alone:                                        {} samples",
        rate(n, st.step, step_cpu)
    );
    let it = st.step + st.adam;
    println!(
        "  per iteration: train_step {:.0} ms ({:.1}%), AdamW over {} params {:.1} ms ({:.1}%) [wall; the process got {:.0}% of {} cores]",
        1e3 * st.step / st.steps as f64,
        100.0 * st.step / it,
        model.n_params(),
        1e3 * st.adam / st.steps as f64,
        100.0 * st.adam / it,
        100.0 * share,
        threads
    );
    let sps_step = n / step_cpu * threads;
    if detail {
        let (f, b) = mlp_macs_per_sample(model);
        let flops = 2.0 * (f + b);
        let p = &st.phases;
        let mlp_time = p.sdf_mlp_fwd + p.color_fwd + p.color_bwd + p.sdf_mlp_bwd;
        let cpu_phases = p.encode_fwd
            + p.sdf_mlp_fwd
            + p.color_fwd
            + p.render
            + p.color_bwd
            + p.sdf_mlp_bwd
            + p.encode_bwd;
        println!(
            "  MLP work: {:.0} MACs/sample forward + {:.0} backward = {:.0} kFLOP/sample -> {:.1} GFLOP/s at the train_step rate = {:.1}% of the FMA peak",
            f,
            b,
            flops / 1e3,
            sps_step * flops / 1e9,
            100.0 * sps_step * flops / peak
        );
        println!(
            "  inside the MLP phases (incl. activations, normals, colour input): {:.1} GFLOP/s per core = {:.1}% of the per-core peak",
            n * flops / (mlp_time * share) / 1e9,
            100.0 * n * flops / (mlp_time * share) / (peak / threads)
        );
        println!(
            "  where train_step's time goes (per sample, one core's time; shares of the phases):"
        );
        let encode = format!("hash encode fwd ({:.2} points)", points_per_sample(model));
        for (name, v) in [
            (encode.as_str(), p.encode_fwd),
            ("SDF MLP fwd", p.sdf_mlp_fwd),
            ("normals + colour MLP fwd", p.color_fwd),
            ("alpha + compositing + loss", p.render),
            ("colour MLP bwd", p.color_bwd),
            ("normal/eikonal + SDF MLP bwd", p.sdf_mlp_bwd),
            ("hash encode bwd (scatter)", p.encode_bwd),
        ] {
            println!(
                "    {name:<30} {:6.2} us {:5.1}%",
                1e6 * v * share / n,
                100.0 * v / cpu_phases
            );
        }
        println!(
            "    {:<30} {:6.2} us (serial, before the parallel part)",
            "ray marching",
            1e6 * p.sample * share / n
        );
        println!(
            "    {:<30} {:6.2} us (summing the shard gradient buffers, parallel)",
            "reduce",
            1e6 * p.reduce * share / n
        );
    }
    sps_step
}

/// Sample points of a realistic batch (ray order) with their finite-difference taps.
fn stencil_points(model: &NeusModel, occ: &OccupancyGrid, n_rays: usize) -> Vec<[[f32; 3]; 7]> {
    let rays = rays_towards_sphere(n_rays, 11);
    let r = model.config.render.radius;
    let s = march_rays(
        &rays.origins,
        &rays.dirs,
        r,
        model.render_step_size(),
        &[],
        Some(occ),
    );
    let eps = model.fd_eps(model.grid.levels.len()) as f32;
    let mut out = Vec::with_capacity(s.n_samples());
    for ray in 0..s.n_rays() {
        let (o, d) = (rays.origins[ray], rays.dirs[ray]);
        for i in s.range(ray) {
            let t = s.t[i];
            let x = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
            let mut pts = [x; 7];
            for k in 0..6 {
                let v = &mut pts[k + 1][k / 2];
                *v = if k % 2 == 0 { *v + eps } else { *v - eps }.clamp(-r, r);
            }
            out.push(pts);
        }
    }
    out
}

/// Distinct 64-byte lines of the hash table the seven points of each sample touch (all levels),
/// and how many of them the previous sample (the neighbour along the ray) did not touch: an
/// estimate of the table traffic beyond the L1 cache. Index arithmetic written here again from
/// the tcnn definition (independent of the library's).
fn hash_lines(model: &NeusModel, pts: &[[[f32; 3]; 7]]) -> (f64, f64) {
    let g = &model.grid;
    let f = g.n_features;
    let mut prev: Vec<u64> = Vec::new();
    let (mut all, mut new) = (0usize, 0usize);
    for sample in pts {
        let mut lines: Vec<u64> = Vec::new();
        for lvl in &g.levels {
            for x in sample {
                let pos: Vec<f64> = x
                    .iter()
                    .map(|&v| lvl.scale * ((v as f64 + 1.0) / 2.0) + 0.5)
                    .collect();
                for c in 0..8u64 {
                    let q: Vec<u64> = (0..3)
                        .map(|d| pos[d].floor() as u64 + ((c >> d) & 1))
                        .collect();
                    let e = if lvl.hashed {
                        (q[0] ^ (q[1] * 2_654_435_761) ^ (q[2] * 805_459_861)) & 0xffff_ffff
                    } else {
                        let r = lvl.resolution as u64;
                        q[0] + q[1] * r + q[2] * r * r
                    } % lvl.size as u64;
                    lines.push((lvl.offset as u64 + e) * 4 * f as u64 / 64);
                }
            }
        }
        lines.sort_unstable();
        lines.dedup();
        all += lines.len();
        new += lines
            .iter()
            .filter(|l| prev.binary_search(l).is_err())
            .count();
        prev = lines;
    }
    (all as f64 / pts.len() as f64, new as f64 / pts.len() as f64)
}

/// The hash-grid encoding of a sample and its six taps, forward and backward, one thread: the
/// general seven-point path (`encode_group`, eight corners per point, reusing the centre's cell),
/// the per-level stencil (`encode_fd`) and the level-parallel batch (`encode_fd_batch`),
/// interleaved so all see the same machine load; best of several rounds.
fn hash_paths(model: &NeusModel, params: &[f32], pts: &[[[f32; 3]; 7]]) {
    let g = &model.grid;
    let d = g.output_dim();
    let table = &params[model.layout.group("hash_grid").unwrap().range()];
    let mut grad = vec![0f32; table.len()];
    let chunk = 512;
    let mut enc = vec![0f32; 7 * chunk * d];
    let rows_of = |i: usize| stencil_rows(i, chunk + 6 * i, d);
    let split = |p: &[[f32; 3]; 7]| (p[0], [0, 1, 2].map(|a| [p[1 + 2 * a][a], p[2 + 2 * a][a]]));
    let active = g.levels.len();
    let rounds: usize = std::env::var("NEUS_AUG_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8);
    let mut best = [f64::MAX; 6];
    let part_len = 16384.min(pts.len() / 2);
    for round in 0..rounds {
        let k0 = (round * part_len) % (pts.len() - part_len + 1);
        let part = &pts[k0..k0 + part_len];
        let xs: Vec<[f32; 3]> = part.iter().map(|p| split(p).0).collect();
        let taps: Vec<[[f32; 2]; 3]> = part.iter().map(|p| split(p).1).collect();
        for (k, b) in best.iter_mut().enumerate() {
            let t = Instant::now();
            for (ci, c) in part.chunks(chunk).enumerate() {
                let r = ci * chunk..ci * chunk + c.len();
                match k {
                    2 => g.encode_fd_batch(
                        table,
                        &xs[r.clone()],
                        &taps[r],
                        1.0,
                        active,
                        &mut enc,
                        |i| (rows_of(i), Sides::Both),
                    ),
                    5 => g.encode_fd_backward_batch(
                        &xs[r.clone()],
                        &taps[r],
                        1.0,
                        active,
                        &enc,
                        |i| (rows_of(i), Sides::Both),
                        &mut grad,
                    ),
                    _ => {
                        for (i, p) in c.iter().enumerate() {
                            let rows = rows_of(i);
                            let (x, tp) = split(p);
                            match k {
                                0 => g.encode_group(table, p, 1.0, active, &mut enc, &rows),
                                1 => g.encode_fd(table, x, tp, 1.0, active, &mut enc, &rows),
                                3 => {
                                    g.encode_group_backward(p, 1.0, active, &enc, &rows, &mut grad)
                                }
                                _ => {
                                    g.encode_fd_backward(x, tp, 1.0, active, &enc, &rows, &mut grad)
                                }
                            }
                        }
                    }
                }
                black_box(&enc);
            }
            *b = b.min(t.elapsed().as_secs_f64() / part.len() as f64);
        }
    }
    let us = best.map(|v| 1e6 * v);
    println!(
        "  hash grid alone, one thread, {part_len} samples x 7 points, us/sample (best of {rounds} rounds):"
    );
    println!(
        "    forward:  general {:.2}, per-level stencil {:.2}, level-parallel batch {:.2} ({:.1}x the general path)",
        us[0], us[1], us[2], us[0] / us[2]
    );
    println!(
        "    backward: general {:.2}, per-level stencil {:.2}, level-parallel batch {:.2} ({:.1}x)",
        us[3],
        us[4],
        us[5],
        us[3] / us[5]
    );
}

/// Parameters perturbed as in `setup` (for models built without it).
fn perturbed(model: &NeusModel) -> Vec<f32> {
    let mut params = model.init_params(0);
    let sdf = model.layout.group("sdf_mlp").unwrap().clone();
    let mut rng = Pcg64Mcg::seed_from_u64(9);
    for v in &mut params[sdf.range()] {
        *v += rng.random_range(-0.01..0.01);
    }
    params
}

/// The `fast` preset's tap layout: `(render.fd_central_every, render.fd_one_sided_span)`.
fn fast_layout() -> (u32, f32) {
    let r = neus_aug::reconstruct::Preset::Fast.config().model.render;
    (r.fd_central_every, r.fd_one_sided_span)
}

/// `render.fd_one_sided_span` from `NEUS_AUG_BENCH_FD_SPAN` (default: the `fast` preset's).
fn fd_span() -> f32 {
    std::env::var("NEUS_AUG_BENCH_FD_SPAN")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(fast_layout().1)
}

/// The main measurement's (and `NEUS_AUG_BENCH_STEP_ONLY`'s) tap layout:
/// `render.fd_central_every` from `NEUS_AUG_BENCH_FD_EVERY` (default: the network's) and the span
/// from [`fd_span`].
fn fd_layout(cfg: &mut ModelConfig) {
    if let Some(k) = std::env::var("NEUS_AUG_BENCH_FD_EVERY")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        cfg.render.fd_central_every = k;
    }
    cfg.render.fd_one_sided_span = fd_span();
}

/// One-sided finite differences as the `fast` preset takes them (`render.fd_central_every = 4`,
/// `render.fd_one_sided_span = 2`) against central ones (the network's default), on the
/// default network: without the curvature loss (the steps before the curvature ramp: every
/// sample one-sided) and with it (the recipe's 5e-4: every fourth sample central, carrying the
/// curvature term). Each pair measured back to back.
fn fd_sides(peak: f64, secs: f64) {
    use neus_aug::render::Scheduled;
    for (phase, curvature) in [("no curvature loss", 0.0), ("curvature loss 5e-4", 5e-4)] {
        let mut rates = [0.0; 2];
        for (j, every) in [1u32, fast_layout().0].into_iter().enumerate() {
            let mut cfg = ModelConfig::default();
            cfg.loss.curvature = Scheduled::Constant(curvature);
            cfg.render.fd_central_every = every;
            cfg.render.fd_one_sided_span = fd_span();
            let (m, mut p, o, _) = setup(cfg);
            let st = train_iterations(&m, &mut p, &o, secs);
            let label = format!(
                "default network, {phase}, render.fd_central_every = {every}, fd_one_sided_span = {}",
                fd_span()
            );
            rates[j] = report(&label, &m, &st, peak, false);
        }
        println!(
            "  one-sided against central differences, {phase}: train_step {:.2}x",
            rates[1] / rates[0]
        );
    }
}

fn main() {
    let secs: f64 = std::env::var("NEUS_AUG_BENCH_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(6.0);
    if let Ok(l2) = std::env::var("NEUS_AUG_BENCH_HASH_ONLY") {
        // Profiling aid: only the hash-grid paths, tables of 2^l2 entries, no occupancy grid.
        let mut cfg = ModelConfig::default();
        cfg.field.hash_grid.log2_hashmap_size = l2.parse().expect("log2 table size");
        cfg.render.occupancy.enabled = false;
        let m = NeusModel::new(cfg).unwrap();
        let p = perturbed(&m);
        let occ = m.new_occupancy_grid();
        hash_paths(&m, &p, &stencil_points(&m, &occ, 60));
        return;
    }
    if std::env::var("NEUS_AUG_BENCH_STEP_ONLY").is_ok() {
        // Profiling aid (callgrind): two training steps of the default network on 64 rays
        // without an occupancy grid, then one AdamW step.
        let mut cfg = ModelConfig::default();
        fd_layout(&mut cfg);
        let model = NeusModel::new(cfg).unwrap();
        let mut params = model.init_params(0);
        let rays = rays_towards_sphere(64, 3);
        let batch = RayBatch {
            origins: &rays.origins,
            dirs: &rays.dirs,
            codes: &[],
            p: &[],
        };
        let t = Targets {
            rgb: &rays.rgb,
            mask: Some(&rays.mask),
        };
        let mut grads = vec![0f32; params.len()];
        let sched = model.config.schedule(1000);
        for k in 0..2 {
            let o = model
                .train_step(&params, &mut grads, &batch, &t, sched, None, k)
                .unwrap();
            println!("{} samples", o.n_samples);
        }
        let mut opt = AdamW::new(AdamWConfig::default(), params.len());
        opt.step_and_zero_grads(&mut params, &mut grads, &model.layout, 1.0)
            .unwrap();
        return;
    }
    let quick = std::env::var("NEUS_AUG_BENCH_QUICK").is_ok();
    let threads = rayon::current_num_threads();
    println!(
        "neus-aug field bench: {threads} rayon threads, load average {} at start",
        loadavg()
    );
    machine();
    let peak = fma_peak();
    let bandwidth = triad_bandwidth();
    if !quick {
        gemm_compare(peak);
        sdf_layer_parts();
    }
    if std::env::var("NEUS_AUG_BENCH_MLP_ONLY").is_ok() {
        return;
    }

    // The default network (DESIGN §5).
    let mut cfg = ModelConfig::default();
    if let Some(c) = std::env::var("NEUS_AUG_CHUNK")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        cfg.render.chunk_samples = c;
    }
    fd_layout(&mut cfg);
    let (model, mut params, occ, (w, cpu)) = setup(cfg);
    println!(
        "\n== SDF queries: occupancy update at warm-up (all {} cells, {:.1}% occupied after): {} points ==",
        occ.n_cells(),
        100.0 * occ.occupied_fraction(),
        rate(occ.n_cells() as f64, w, cpu)
    );
    let st = train_iterations(&model, &mut params, &occ, secs);
    let sps = report(
        "training iteration, default network (L=16, F=2, T=2^19, SDF 35->64->13, colour 32->64->64->3)",
        &model,
        &st,
        peak,
        true,
    );
    println!(
        "  target 400k samples/s (train_step, 2 idle cores): {:.0}% of target",
        100.0 * sps / 4e5
    );
    let pts = stencil_points(&model, &occ, 200);
    let (lines, new) = hash_lines(&model, &pts[..pts.len().min(20000)]);
    let g = &model.grid;
    println!(
        "  hash table {:.1} MB ({} levels, {} dense) + its gradient buffer(s), L3 {}: per sample the 7 points touch {:.0} distinct 64-B lines, {:.0} not touched by the previous sample; at the train_step rate that is ~{:.1} GB/s of table reads + {:.1} GB/s of gradient read-modify-write beyond L1 ({:.0}% of the triad bandwidth)",
        (g.n_params() * 4) as f64 / 1e6,
        g.levels.len(),
        g.levels.iter().filter(|l| !l.hashed).count(),
        l3_cache().unwrap_or_else(|| "unknown".into()),
        lines,
        new,
        sps * new * 64.0 / 1e9,
        sps * new * 128.0 / 1e9,
        100.0 * sps * new * 192.0 / bandwidth
    );
    if let Some(l) = std::fs::read_to_string("/proc/self/smaps_rollup")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("AnonHugePages"))
                .map(String::from)
        })
    {
        println!(
            "  memory in transparent huge pages (LargeAligned allocator): {}",
            l.split_whitespace().skip(1).collect::<Vec<_>>().join(" ")
        );
    }
    fd_sides(peak, secs / 2.0);
    if quick {
        println!("load average at end: {}", loadavg());
        return;
    }
    hash_paths(&model, &params, &pts);

    // Smaller tables, as CPU presets may use.
    for log2 in [17u32, 16] {
        let mut cfg = ModelConfig::default();
        cfg.field.hash_grid.log2_hashmap_size = log2;
        let (m, mut p, o, _) = setup(cfg);
        let st = train_iterations(&m, &mut p, &o, secs / 2.0);
        report(
            &format!("T = 2^{log2}, otherwise default"),
            &m,
            &st,
            peak,
            false,
        );
    }

    // Inference rendering (no backward) on the default model.
    let rays = rays_towards_sphere(1024, 5);
    let batch = RayBatch {
        origins: &rays.origins,
        dirs: &rays.dirs,
        codes: &[],
        p: &[],
    };
    let isched = model.config.inference_schedule(1000);
    let r = model.render(&params, &batch, isched, Some(&occ)).unwrap();
    let c = Clock::start();
    let mut k = 0;
    while c.wall.elapsed().as_secs_f64() < secs / 4.0 || k < 2 {
        black_box(model.render(&params, &batch, isched, Some(&occ)).unwrap());
        k += 1;
    }
    let (w, cpu) = c.stop();
    println!(
        "\n== render (forward only, FD normals, {} samples per 1024 rays): {} samples ==",
        r.n_samples,
        rate((r.n_samples * k) as f64, w, cpu)
    );
    // SDF queries at random points (marching cubes and occupancy updates use the same path).
    let mut rng = Pcg64Mcg::seed_from_u64(12);
    let pts: Vec<[f32; 3]> = (0..1 << 20)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
        .collect();
    black_box(model.sdf(&params, &pts[..1 << 14], 16));
    let c = Clock::start();
    black_box(model.sdf(&params, &pts, 16));
    let (w, cpu) = c.stop();
    println!(
        "== sdf queries at random points (no locality): {} points ==",
        rate(pts.len() as f64, w, cpu)
    );
    println!("load average at end: {}", loadavg());
}
