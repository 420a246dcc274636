use super::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Random `A`, `B`, `C` (padded leading dimensions, a spare element after `A`).
#[allow(clippy::type_complexity)]
fn operands<T: Real>(
    rng: &mut Pcg64Mcg,
    m: usize,
    kk: usize,
    n: usize,
) -> (Vec<T>, Vec<T>, Vec<T>, Vec<T>) {
    let mut v = |len: usize| -> Vec<T> {
        (0..len)
            .map(|_| T::from_f64(rng.random_range(-1.0..1.0)))
            .collect()
    };
    let (ldb, ldc) = (n + 3, n + 2);
    (v(m * kk + 1), v(kk * ldb), v(m * ldc), v(n))
}

/// The left operand `A` (`m × kk`): row-major, or the transpose of a row-major `kk × m`.
fn a_operand<T>(a: &[T], m: usize, kk: usize, transposed: bool) -> Strided<'_, T> {
    if transposed {
        Strided::transposed(a, m)
    } else {
        Strided::row_major(a, kk)
    }
}

/// `C₀` through `kernel` with [`operands`]' leading dimensions (`ldb = n + 3`, `ldc = n + 2`)
/// and the epilogue `f`: the resulting `C`, with the explicit-register tiles allowed (`SIMD`)
/// or not (the portable loops alone).
#[allow(clippy::too_many_arguments)]
fn through_as<T: Real, const SIMD: bool>(
    kernel: Kernel,
    m: usize,
    kk: usize,
    n: usize,
    sa: Strided<T>,
    b: &[T],
    c0: &[T],
    init: Init<T>,
    f: impl FnMut(usize, &mut [T]),
) -> Vec<T> {
    let mut c = c0.to_vec();
    run::<T, _, SIMD>(kernel, m, kk, n, sa, b, n + 3, &mut c, n + 2, init, f);
    c
}

/// Every `f32` case of the bit-for-bit tests, from `seed`: each of [`SHAPES`] in both
/// orientations with each [`Init`]. `check` gets the case's label and `run(kernel, simd)`,
/// which returns `C` through that kernel (explicit registers allowed or not) with an epilogue
/// that clamps from below, so the epilogue's place in the kernel is compared too.
fn for_each_f32_case(seed: u64, mut check: impl FnMut(&str, &dyn Fn(Kernel, bool) -> Vec<f32>)) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    for &(m, kk, n) in &SHAPES {
        for transposed in [false, true] {
            for init_kind in 0..3 {
                let (a, b, c0, bias) = operands::<f32>(&mut rng, m, kk, n);
                let (sa, init) = (a_operand(&a, m, kk, transposed), init_of(init_kind, &bias));
                let clamp = |_: usize, row: &mut [f32]| {
                    for v in row.iter_mut() {
                        *v = v.max(0.25);
                    }
                };
                let run = |kernel: Kernel, simd: bool| {
                    if simd {
                        through_as::<f32, true>(kernel, m, kk, n, sa, &b, &c0, init, clamp)
                    } else {
                        through_as::<f32, false>(kernel, m, kk, n, sa, &b, &c0, init, clamp)
                    }
                };
                let case =
                    format!("m {m}, k {kk}, n {n}, transposed {transposed}, init {init_kind}");
                check(&case, &run);
            }
        }
    }
}

/// Whether two results are the same floats, bit for bit.
fn same_bits(x: &[f32], y: &[f32]) -> bool {
    x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
}

/// [`Init`] number `kind`: 0 zero, 1 accumulate, otherwise the bias row.
fn init_of<T>(kind: usize, bias: &[T]) -> Init<'_, T> {
    match kind {
        0 => Init::Zero,
        1 => Init::Accumulate,
        _ => Init::Bias(bias),
    }
}

const SHAPES: [(usize, usize, usize); 14] = [
    (13, 35, 64),
    (7, 64, 32),
    (35, 100, 64),
    (5, 9, 16),
    (6, 7, 13),
    (1, 1, 64),
    (4, 0, 32),
    (12, 5, 64),
    (11, 3, 32),
    (17, 64, 16),
    (23, 35, 64),
    (9, 40, 32),
    // Longer than one chunk of the panel kernel's k loop (`PANEL_KC`), with a remainder.
    (35, 600, 64),
    (13, 515, 32),
];

/// Every kernel (the build's and the others), every specialised width and the fallback, both
/// operand orientations, every [`Init`], row counts that leave each remainder, in `f64`
/// against `matrixmultiply`; the epilogue sees each row once, finished.
#[test]
fn kernels_match_matrixmultiply() {
    let mut rng = Pcg64Mcg::seed_from_u64(31);
    let mut worst = 0.0f64;
    for kernel in Kernel::ALL {
        for &(m, kk, n) in &SHAPES {
            for transposed in [false, true] {
                for init_kind in 0..3 {
                    let (a, b, c0, bias) = operands::<f64>(&mut rng, m, kk, n);
                    let (ldb, ldc) = (n + 3, n + 2);
                    let (sa, init) = (a_operand(&a, m, kk, transposed), init_of(init_kind, &bias));
                    let mut c1 = c0.clone();
                    let mut seen = vec![0usize; m];
                    gemm_then_with(
                        kernel,
                        m,
                        kk,
                        n,
                        sa,
                        &b,
                        ldb,
                        &mut c1,
                        ldc,
                        init,
                        |i, row| {
                            seen[i] += 1;
                            // A visible epilogue: the tests below see it applied exactly once.
                            for v in row.iter_mut() {
                                *v = 2.0 * *v + 1.0;
                            }
                        },
                    );
                    assert!(seen.iter().all(|&s| s == 1), "{kernel:?} epilogue {seen:?}");
                    let mut c2 = c0.clone();
                    if init_kind == 2 {
                        for i in 0..m {
                            c2[i * ldc..i * ldc + n].copy_from_slice(&bias);
                        }
                    }
                    gemm_reference(m, kk, n, sa, &b, ldb, &mut c2, ldc, init_kind != 0);
                    for i in 0..m {
                        for j in 0..ldc {
                            let (got, want) = (c1[i * ldc + j], c2[i * ldc + j]);
                            // Padding columns are untouched; the others got the epilogue.
                            let want = if j < n { 2.0 * want + 1.0 } else { want };
                            worst = worst.max((got - want).abs());
                        }
                    }
                }
            }
        }
    }
    assert!(worst < 1e-12, "register kernels vs matrixmultiply: {worst}");
}

/// The `f32` instantiations (the ones that train, vectorised differently from `f64`) of every
/// kernel against the `f64` product of the same inputs, and [`gemm`] itself (the build's
/// [`KERNEL`]).
#[test]
fn f32_kernels_match_f64() {
    let mut rng = Pcg64Mcg::seed_from_u64(32);
    let mut worst = 0.0f64;
    for &(m, kk, n) in &SHAPES {
        for transposed in [false, true] {
            let (a, b, c0, _) = operands::<f32>(&mut rng, m, kk, n);
            let (ldb, ldc) = (n + 3, n + 2);
            let up = |v: &[f32]| -> Vec<f64> { v.iter().map(|&x| x as f64).collect() };
            let (a64, b64) = (up(&a), up(&b));
            let (sa, sa64) = if transposed {
                (
                    Strided::transposed(&a[..], m),
                    Strided::transposed(&a64[..], m),
                )
            } else {
                (
                    Strided::row_major(&a[..], kk),
                    Strided::row_major(&a64[..], kk),
                )
            };
            let mut want = up(&c0);
            gemm_reference(m, kk, n, sa64, &b64, ldb, &mut want, ldc, true);
            let mut check = |c: &[f32]| {
                for (g, w) in c.iter().zip(&want) {
                    // |error| ≤ (k+1)·2⁻²⁴·Σ|terms| with |terms| ≤ 1: scale by k + 1.
                    worst = worst.max((*g as f64 - w).abs() / (kk as f64 + 1.0));
                }
            };
            for kernel in Kernel::ALL {
                check(&through_as::<_, true>(
                    kernel,
                    m,
                    kk,
                    n,
                    sa,
                    &b,
                    &c0,
                    Init::Accumulate,
                    |_, _| {},
                ));
            }
            let mut c = c0.clone();
            gemm(m, kk, n, sa, &b, ldb, &mut c, ldc, Init::Accumulate);
            check(&c);
        }
    }
    assert!(worst < 2.0f64.powi(-22), "f32 kernels vs f64: {worst:e}");
}

/// The two register kernels add the same terms in the same order with one fused
/// multiply-add each, so in `f32` they agree bit for bit, whichever of them runs in explicit
/// registers and whichever the compiler vectorised. On AVX-512 builds the widths 32 and 64
/// compare [`zmm_tile`] with [`ymm_panel`]; at width 16 the panel is the whole tile, so both
/// kernels take [`zmm_tile`] there. On AVX2 builds [`ymm_panel`] meets the compiler's spilled
/// wide tiles.
#[test]
fn register_kernels_agree_bit_for_bit_in_f32() {
    for_each_f32_case(33, |case, run| {
        let (wide, panel) = (run(Kernel::WideTiles, true), run(Kernel::PanelTiles, true));
        assert!(same_bits(&wide, &panel), "{case}");
    });
}

/// The explicit-register tiles ([`zmm_tile`] on AVX-512 builds, [`ymm_panel`] on AVX2 + FMA
/// builds) against the portable loops they replace, kernel by kernel, in `f32`: bit for bit,
/// with an epilogue, every width, orientation, [`Init`] and row remainder of [`SHAPES`] (on
/// builds without those ISAs both sides run the portable loops).
#[test]
fn explicit_registers_agree_bit_for_bit_with_portable_loops() {
    for_each_f32_case(34, |case, run| {
        for kernel in [Kernel::WideTiles, Kernel::PanelTiles] {
            let (fast, portable) = (run(kernel, true), run(kernel, false));
            assert!(same_bits(&fast, &portable), "{kernel:?}: {case}");
        }
    });
}

/// Cutting the sum over `k` into chunks changes no bit: every output adds its terms in the
/// same order with the same roundings, whatever the chunk (here against one chunk, in `f32`
/// where a reordered sum would show), on the weight gradient's transposed operand.
#[test]
fn k_chunks_are_bit_identical_to_one_sum() {
    /// `C + A·B` through the panel kernel with `k` chunks of `KC` (0: one chunk).
    fn sum<const KC: usize>(
        m: usize,
        kk: usize,
        a: Strided<f32>,
        b: &[f32],
        c0: &[f32],
    ) -> Vec<f32> {
        let mut c = c0.to_vec();
        let mut none = |_: usize, _: &mut [f32]| {};
        let (ldb, ldc) = (64 + 3, 64 + 2);
        blocks::<f32, _, 64, 16, 6, KC, true>(
            m,
            kk,
            a,
            b,
            ldb,
            &mut c,
            ldc,
            Init::Accumulate,
            &mut none,
        );
        c
    }
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    for &(m, kk) in &[(35usize, 600usize), (13, 515), (6, 64), (7, 65)] {
        let (a, b, c0, _) = operands::<f32>(&mut rng, m, kk, 64);
        let sa = Strided::transposed(&a[..], m);
        let (one, chunks) = (
            sum::<0>(m, kk, sa, &b, &c0),
            sum::<PANEL_KC>(m, kk, sa, &b, &c0),
        );
        assert!(
            one.iter()
                .zip(&chunks)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "m {m}, k {kk}: chunked sums differ"
        );
    }
}

/// The kernel chosen at build time can run on the CPU running the tests (the build's target
/// features are present), and the fast kernels specialise only the widths they have tiles for.
#[test]
fn build_selects_a_kernel_this_cpu_runs() {
    #[cfg(target_arch = "x86_64")]
    match KERNEL {
        Kernel::WideTiles => assert!(std::arch::is_x86_feature_detected!("avx512f")),
        Kernel::PanelTiles => assert!(
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
        ),
        Kernel::MatrixMultiply => {}
    }
    assert!(!Kernel::MatrixMultiply.specialises(64));
    assert!(Kernel::PanelTiles.specialises(16) && !Kernel::WideTiles.specialises(13));
}
