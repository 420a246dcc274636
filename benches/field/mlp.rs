//! The MLP products of the `field` bench (its part 2): the `field::dense` kernels against
//! `matrixmultiply` and the naive triple loop, and the SDF hidden layer's parts.

use super::machine::matrixmultiply_kernel;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use std::hint::black_box;
use std::time::Instant;

/// The SDF network's hidden layer on a chunk's rows (256 samples × 7 points): the product alone,
/// with the fused Softplus, and the whole forward + backward of the layer.
pub(crate) fn sdf_layer_parts() {
    use neus_aug::field::mlp::{linear_forward, MlpTape};
    use neus_aug::field::{Activation, Mlp};
    let mlp = Mlp::new(vec![35, 64, 13], Activation::Softplus { beta: 100.0 });
    let mut rng = Pcg64Mcg::seed_from_u64(4);
    let p: Vec<f32> = (0..mlp.n_params())
        .map(|_| rng.random_range(-0.3..0.3))
        .collect();
    let rows = 1792;
    let x: Vec<f32> = (0..rows * 35)
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let mut y = vec![0f32; rows * 64];
    let mut tape = MlpTape::default();
    let mut g = vec![0f32; mlp.n_params()];
    let mut dh = vec![0f32; rows * 64];
    let mut scratch = Vec::new();
    let mut dx = vec![0f32; rows * 35];
    let mut best = [f64::MAX; 3];
    for _ in 0..20 {
        for (v, b) in best.iter_mut().enumerate() {
            let t = Instant::now();
            for _ in 0..20 {
                match v {
                    0 => linear_forward(
                        &p[..64 * 35],
                        &p[64 * 35..64 * 36],
                        &x,
                        rows,
                        35,
                        64,
                        &mut y,
                    ),
                    1 => mlp.forward_hidden(&p, &x, rows, &mut tape),
                    _ => {
                        dh.fill(0.01);
                        mlp.backward_hidden_cols(
                            &p,
                            &mut g,
                            &x,
                            rows,
                            &tape,
                            &mut dh,
                            &mut scratch,
                            Some((&mut dx, 3..35)),
                        );
                    }
                }
                black_box(&y);
            }
            *b = b.min(t.elapsed().as_secs_f64() / (20 * rows / 7) as f64);
        }
    }
    let mut sp = f64::MAX;
    let mut d = vec![0f32; rows * 64];
    for _ in 0..20 {
        let t = Instant::now();
        for _ in 0..20 {
            for (v, dv) in y.iter_mut().zip(d.iter_mut()) {
                let (a, s) = neus_aug::field::fastmath::softplus_f32(*v, 100.0);
                *v = a;
                *dv = s;
            }
            black_box(&y);
        }
        sp = sp.min(t.elapsed().as_secs_f64() / (20 * rows / 7) as f64);
    }
    println!("  softplus alone: {:.3} us/sample", sp * 1e6);
    let fl = 2.0 * 7.0 * 35.0 * 64.0;
    println!(
        "  SDF hidden layer per sample (7 rows): product {:.3} us ({:.0} GFLOP/s), + Softplus {:.3} us, backward (dW, dX grid cols, dz) {:.3} us ({:.0} GFLOP/s)",
        1e6 * best[0],
        fl / best[0] / 1e9,
        1e6 * best[1],
        1e6 * best[2],
        (2.0 * fl - 2.0 * 7.0 * 3.0 * 64.0) / best[2] / 1e9
    );
}

/// The MLP products on one thread: each [`Kernel`](neus_aug::field::dense::Kernel) (the build's
/// marked `*`; `matrixmultiply` is the peer the dispatch rule is judged against) and the naive
/// triple loop, runs interleaved so that load on the machine hits them alike; best of 5. The last
/// column is the build's kernel over `matrixmultiply` (≥ 0.90 is the target on every shape).
pub(crate) fn gemm_compare(peak: f64) {
    use neus_aug::field::dense::{gemm_then_with, Init, Kernel, Strided, KERNEL};
    let threads = rayon::current_num_threads() as f64;
    let per_core = peak / threads / 1e9;
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    let mm = matrixmultiply_kernel();
    println!(
        "\n== MLP products, one thread, f32, GFLOP/s (% of the per-core FMA peak {per_core:.0}), best of 5; build kernel: {KERNEL:?}; matrixmultiply runs its {mm} kernel here =="
    );
    if mm == "AVX-512F" && !cfg!(target_feature = "avx512f") {
        println!(
            "  note: this build targets CPUs without AVX-512, but the crate chooses at run time and runs AVX-512 here; on an AVX2-only CPU it runs its AVX2 + FMA kernel. Build with MMTEST_FEATURE=avx,avx2,fma (the crate's switch) to measure that peer."
        );
    }
    let names: Vec<String> = Kernel::ALL
        .iter()
        .map(|k| format!("{}{k:?}", if *k == KERNEL { "*" } else { "" }))
        .collect();
    println!(
        "  {:<30} {:>15} {:>15} {:>15} {:>7}  build/mm",
        "shape", names[0], names[1], names[2], "naive"
    );
    let mut worst = f64::MAX;
    for &(m, k, n, tr, name) in &[
        (3584usize, 35usize, 64usize, false, "fwd  [3584 x 35] -> 64"),
        (512, 64, 64, false, "fwd  [512 x 64] -> 64"),
        (3584, 64, 32, false, "dX   [3584 x 64] -> 32"),
        (35, 3584, 64, true, "dW   64 x 35 over 3584 rows"),
        (512, 64, 16, false, "fwd  [512 x 64] -> 13 (16)"),
        (512, 35, 64, false, "fwd  [512 x 35] -> 64"),
        (3584, 64, 64, false, "fwd  [3584 x 64] -> 64"),
        (36, 3584, 64, true, "dW   64 x 36 over 3584 rows"),
        (64, 512, 16, true, "dW   16 x 64 over 512 rows"),
    ] {
        let a: Vec<f32> = (0..m * k).map(|_| rng.random_range(-1.0..1.0)).collect();
        let b: Vec<f32> = (0..k * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut c = vec![0f32; m * n];
        let sa = if tr {
            Strided::transposed(&a[..], m)
        } else {
            Strided::row_major(&a[..], k)
        };
        let flops = 2.0 * (m * k * n) as f64;
        let reps = (4e9 / flops).ceil() as usize;
        let mut g = [0.0f64; 4];
        // Five rounds, each timing every variant once (~20 ms each).
        for _ in 0..5 {
            for (v, gv) in g.iter_mut().enumerate() {
                let reps = if v == 3 { reps.div_ceil(32) } else { reps };
                let t = Instant::now();
                for _ in 0..reps {
                    if v < 3 {
                        gemm_then_with(
                            Kernel::ALL[v],
                            m,
                            k,
                            n,
                            sa,
                            &b,
                            n,
                            &mut c,
                            n,
                            Init::Zero,
                            |_, _| {},
                        );
                    } else {
                        for i in 0..m {
                            for j in 0..n {
                                let mut s = 0.0;
                                for kk in 0..k {
                                    s += a[i * sa.rs + kk * sa.cs] * b[kk * n + j];
                                }
                                c[i * n + j] = s;
                            }
                        }
                    }
                    black_box(&c);
                }
                *gv = gv.max(flops * reps as f64 / t.elapsed().as_secs_f64() / 1e9);
            }
        }
        let build = g[Kernel::ALL.iter().position(|&k| k == KERNEL).unwrap_or(2)];
        let ratio = build / g[2];
        worst = worst.min(ratio);
        println!(
            "  {name:<30} {:7.1} ({:3.0}%) {:7.1} ({:3.0}%) {:7.1} ({:3.0}%) {:7.1}  {:.2}",
            g[0],
            100.0 * g[0] / per_core,
            g[1],
            100.0 * g[1] / per_core,
            g[2],
            100.0 * g[2] / per_core,
            g[3],
            ratio
        );
    }
    println!(
        "  worst build/matrixmultiply ratio over these shapes: {worst:.2} (against the crate's {mm} kernel)"
    );
}
