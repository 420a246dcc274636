//! Register-blocked matrix products for the MLPs' thin shapes (`[rows × 35] → 64`,
//! `[rows × 64] → 64`, weight gradients summed over thousands of rows).
//!
//! One micro-kernel serves every product: `C[i][0..N] (+)= Σ_k a(i, k) · B[k][0..N]`, where
//! `a(i, k) = A[i·rs + k·cs]` may be strided either way and `B` rows are contiguous. `R` rows of
//! `C` stay in registers while `k` runs, each step broadcasting `R` values of `A` against one row
//! (or one `P`-wide panel of a row) of `B`. With `N`, `P`, `R` fixed at compile time the compiler
//! keeps the accumulators in registers and turns the row loop into vector FMAs; no packing, no
//! allocation. An epilogue `f(i, row)` sees each finished row before it is stored (the MLPs fuse
//! their activation and its derivative there).
//!
//! # Which kernel a build uses ([`KERNEL`], fixed at compile time by `target_feature`)
//!
//! | build | [`Kernel`] | why |
//! |---|---|---|
//! | x86-64 with AVX-512 (`target-cpu=native` on Zen 4, Skylake-X, …) | [`Kernel::WideTiles`] | the whole `6 × 64` (`8 × 32`, `8 × 16`) tile in 24–32 of the 32 `zmm` registers; for `f32` through explicit intrinsics (`zmm_tile`), since LLVM's Intel tuning would otherwise vectorise it 256 bits wide |
//! | x86-64 with AVX2 + FMA, no AVX-512 (Zen 2/3, Haswell … Alder Lake, `x86-64-v3`) | [`Kernel::PanelTiles`] | the wide tiles need 48 `ymm` accumulators for `N` = 64 and spill; `6 × 16` panels use 12 of the 16 (for `f32` through explicit intrinsics, `ymm_panel`), and sums longer than [`PANEL_KC`] go in `k` chunks that stay in L1 |
//! | anything else (`x86-64-v2`, no target flags, aarch64, …) | [`Kernel::MatrixMultiply`] | `matrixmultiply` picks its own kernel at run time (AVX-512, AVX2+FMA, AVX, SSE2, NEON), so a portable binary still gets the CPU's vector units; portable Rust compiled for SSE2 or unmeasured NEON would not do better |
//!
//! Widths other than 16/32/64 always go to `matrixmultiply` ([`Real::gemm`]), which is also the
//! reference every kernel is tested against, on every build ([`gemm_then_with`] runs any kernel
//! anywhere: they are all portable Rust, only their register shape targets one ISA).
//!
//! `cargo bench --bench field` (`NEUS_AUG_BENCH_MLP_ONLY=1` for this part) prints every kernel
//! beside `matrixmultiply` in the same run; on the AMD and Intel CPUs measured, each build's tiles
//! run at about 1.2–2.5× the crate's kernel for the same instruction set over the MLP shapes, and
//! the wide tiles spill in an AVX2 build (measured: docs/benchmarks.md). `matrixmultiply` chooses
//! its kernel at run time, so on an AVX-512 CPU even an `x86-64-v3` build compares with its AVX-512
//! kernel, not the AVX2 one that AVX2-only CPUs get; `MMTEST_FEATURE=avx,avx2,fma` at build time
//! holds it to the latter.
//!
//! Generic over [`Real`]: the `f64` gradient checks run the same code.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::Real;

/// A matrix operand `a(i, k) = data[i·rs + k·cs]`.
#[derive(Clone, Copy)]
pub struct Strided<'a, T> {
    pub data: &'a [T],
    pub rs: usize,
    pub cs: usize,
}

impl<'a, T> Strided<'a, T> {
    /// A row-major matrix with leading dimension `ld`: `a(i, k) = data[i·ld + k]`.
    pub fn row_major(data: &'a [T], ld: usize) -> Self {
        Self {
            data,
            rs: ld,
            cs: 1,
        }
    }

    /// The transpose of a row-major matrix with leading dimension `ld`:
    /// `a(i, k) = data[k·ld + i]`.
    pub fn transposed(data: &'a [T], ld: usize) -> Self {
        Self {
            data,
            rs: 1,
            cs: ld,
        }
    }
}

/// What `C` starts from before the products are added.
#[derive(Clone, Copy)]
pub enum Init<'a, T> {
    /// Zeros.
    Zero,
    /// The current contents of `C`.
    Accumulate,
    /// The same row `bias[0..n]` for every row.
    Bias(&'a [T]),
}

/// The implementations of the width-16/32/64 products (see the module docs for which build
/// uses which, and why).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// The whole `R × N` tile of `C` in registers (`N` = 64, 32, 16 with `R` = 6, 8, 8): 24–32
    /// accumulators, which needs the 32 vector registers of AVX-512.
    WideTiles,
    /// 6 rows × 16 columns at a time (12 accumulators, two `B` vectors and a broadcast for `f32`
    /// on AVX2's 16 `ymm` registers), panel by panel; the epilogue runs on the finished rows
    /// parked in L1.
    PanelTiles,
    /// `matrixmultiply` (its own run-time ISA dispatch: AVX-512, AVX2+FMA, AVX, SSE2, NEON, …)
    /// with the epilogue on the stored rows.
    MatrixMultiply,
}

impl Kernel {
    /// Every kernel, for tests and the bench.
    pub const ALL: [Kernel; 3] = [
        Kernel::WideTiles,
        Kernel::PanelTiles,
        Kernel::MatrixMultiply,
    ];

    /// Whether this kernel has a register path for output width `n` (else `n` goes to
    /// `matrixmultiply`).
    pub fn specialises(self, n: usize) -> bool {
        self != Kernel::MatrixMultiply && matches!(n, 16 | 32 | 64)
    }
}

/// The `k` chunk of [`Kernel::PanelTiles`]: 64 rows of the weight gradient's operands, `64 × 64`
/// of `B` (16 KB in `f32`) and `64 × 35` of `A` (9 KB), fit in a 32 KB L1 together, so the
/// `⌈35/6⌉ × 4` panel passes over a chunk read L1 instead of L2: the weight-gradient product
/// runs about 1.2× faster than with chunks of 256 rows (measured: docs/benchmarks.md). The sums
/// are bit-identical for any chunk.
pub const PANEL_KC: usize = 64;

/// The kernel this build uses, chosen from the target features it is compiled for.
pub const KERNEL: Kernel = if cfg!(all(target_arch = "x86_64", target_feature = "avx512f")) {
    Kernel::WideTiles
} else if cfg!(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
)) {
    Kernel::PanelTiles
} else {
    Kernel::MatrixMultiply
};

/// `C[i][0..n] = init + Σ_{k<kk} a(i, k) · B[k][0..n]` for `i < m`; `B` row `k` at
/// `b[k·ldb..]`, `C` row `i` at `c[i·ldc..]`.
#[allow(clippy::too_many_arguments)]
pub fn gemm<T: Real>(
    m: usize,
    kk: usize,
    n: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
) {
    gemm_then(m, kk, n, a, b, ldb, c, ldc, init, |_, _| {});
}

/// [`gemm`] with an epilogue: `f(i, row)` is called on each finished row of `C` (`n` values)
/// while it is still in registers, before it is stored (fused bias-free activations and the
/// like). For widths without a specialised kernel the epilogue runs on the stored row.
#[allow(clippy::too_many_arguments)]
pub fn gemm_then<T: Real, F: FnMut(usize, &mut [T])>(
    m: usize,
    kk: usize,
    n: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    f: F,
) {
    gemm_then_with(KERNEL, m, kk, n, a, b, ldb, c, ldc, init, f);
}

/// [`gemm_then`] through a named [`Kernel`] rather than the build's [`KERNEL`]: every kernel is
/// portable Rust, so the tests and the bench can run all of them on any build (a kernel meant for
/// another ISA is correct here, only not fast). Widths other than 16/32/64 always take the
/// [`Kernel::MatrixMultiply`] path.
#[allow(clippy::too_many_arguments)]
pub fn gemm_then_with<T: Real, F: FnMut(usize, &mut [T])>(
    kernel: Kernel,
    m: usize,
    kk: usize,
    n: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    f: F,
) {
    run::<T, F, true>(kernel, m, kk, n, a, b, ldb, c, ldc, init, f);
}

/// [`gemm_then_with`], with the explicit-register tiles ([`zmm_tile`], [`ymm_panel`]) allowed
/// (`SIMD`, as every caller outside the tests has it) or not (the portable loops alone, which
/// the tests compare them with).
#[allow(clippy::too_many_arguments)]
fn run<T: Real, F: FnMut(usize, &mut [T]), const SIMD: bool>(
    kernel: Kernel,
    m: usize,
    kk: usize,
    n: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    mut f: F,
) {
    if m == 0 || n == 0 {
        return;
    }
    assert!(
        kk == 0 || (m - 1) * a.rs + (kk - 1) * a.cs < a.data.len(),
        "A too short"
    );
    assert!(kk == 0 || (kk - 1) * ldb + n <= b.len(), "B too short");
    assert!((m - 1) * ldc + n <= c.len(), "C too short");
    if let Init::Bias(bias) = init {
        assert!(bias.len() >= n, "bias too short");
    }
    let f = &mut f;
    match (kernel, n) {
        (Kernel::WideTiles, 64) => {
            blocks::<T, F, 64, 64, 6, 0, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        (Kernel::WideTiles, 32) => {
            blocks::<T, F, 32, 32, 8, 0, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        (Kernel::WideTiles, 16) => {
            blocks::<T, F, 16, 16, 8, 0, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        (Kernel::PanelTiles, 64) => {
            blocks::<T, F, 64, 16, 6, PANEL_KC, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        (Kernel::PanelTiles, 32) => {
            blocks::<T, F, 32, 16, 6, PANEL_KC, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        (Kernel::PanelTiles, 16) => {
            blocks::<T, F, 16, 16, 6, PANEL_KC, SIMD>(m, kk, a, b, ldb, c, ldc, init, f)
        }
        _ => {
            if let Init::Bias(bias) = init {
                for i in 0..m {
                    c[i * ldc..i * ldc + n].copy_from_slice(&bias[..n]);
                }
            }
            let acc = !matches!(init, Init::Zero);
            gemm_reference(m, kk, n, a, b, ldb, c, ldc, acc);
            for i in 0..m {
                f(i, &mut c[i * ldc..i * ldc + n]);
            }
        }
    }
}

/// `C = (C if accumulate else 0) + A·B` through [`Real::gemm`] (`matrixmultiply`): the
/// reference of the register kernels and the path for other widths.
#[allow(clippy::too_many_arguments)]
pub fn gemm_reference<T: Real>(
    m: usize,
    kk: usize,
    n: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    accumulate: bool,
) {
    if m == 0 || n == 0 {
        return;
    }
    if kk == 0 {
        if !accumulate {
            for i in 0..m {
                c[i * ldc..i * ldc + n].fill(T::ZERO);
            }
        }
        return;
    }
    assert!(
        (m - 1) * a.rs + (kk - 1) * a.cs < a.data.len(),
        "A too short"
    );
    assert!((kk - 1) * ldb + n <= b.len(), "B too short");
    assert!((m - 1) * ldc + n <= c.len(), "C too short");
    // SAFETY: the extents were checked above; C does not overlap A or B (distinct borrows).
    unsafe {
        T::gemm(
            m,
            kk,
            n,
            T::ONE,
            a.data.as_ptr(),
            a.rs as isize,
            a.cs as isize,
            b.as_ptr(),
            ldb as isize,
            1,
            if accumulate { T::ONE } else { T::ZERO },
            c.as_mut_ptr(),
            ldc as isize,
            1,
        );
    }
}

/// All rows of `C`, with the sum over `k` cut into chunks of `KC` (0: one chunk) when it is
/// longer: the weight gradients sum over thousands of rows, and a chunk of `A` and `B` stays in
/// cache while every row block sweeps it (see [`PANEL_KC`]), instead of streaming all of `B`
/// from L2 or L3 once per row block. `C` carries the
/// partial sums between chunks; each output still adds its terms in the order `k = 0, 1, …`
/// with the same roundings, so the result is bit-identical to one chunk. The epilogue runs on
/// the last chunk only.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn blocks<
    T: Real,
    F: FnMut(usize, &mut [T]),
    const N: usize,
    const P: usize,
    const R: usize,
    const KC: usize,
    const SIMD: bool,
>(
    m: usize,
    kk: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    f: &mut F,
) {
    if KC == 0 || kk <= KC {
        row_blocks::<T, F, N, P, R, SIMD>(m, kk, a, b, ldb, c, ldc, init, f);
        return;
    }
    let mut k0 = 0;
    while k0 < kk {
        let k1 = (k0 + KC).min(kk);
        let ak = Strided {
            data: &a.data[k0 * a.cs..],
            rs: a.rs,
            cs: a.cs,
        };
        let bk = &b[k0 * ldb..];
        let init_k = if k0 == 0 { init } else { Init::Accumulate };
        if k1 == kk {
            row_blocks::<T, F, N, P, R, SIMD>(m, k1 - k0, ak, bk, ldb, c, ldc, init_k, f);
        } else {
            let mut none = |_: usize, _: &mut [T]| {};
            row_blocks::<T, _, N, P, R, SIMD>(m, k1 - k0, ak, bk, ldb, c, ldc, init_k, &mut none);
        }
        k0 = k1;
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn row_blocks<
    T: Real,
    F: FnMut(usize, &mut [T]),
    const N: usize,
    const P: usize,
    const R: usize,
    const SIMD: bool,
>(
    m: usize,
    kk: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    f: &mut F,
) {
    let mut i0 = 0;
    while i0 + R <= m {
        tile::<T, F, N, P, R, SIMD>(i0, kk, a, b, ldb, c, ldc, init, f);
        i0 += R;
    }
    // Remaining rows, as few passes over B as possible.
    let rest = m - i0;
    macro_rules! rest {
        ($($r:literal)*) => {
            match rest {
                0 => {}
                $($r if $r < R => tile::<T, F, N, P, $r, SIMD>(i0, kk, a, b, ldb, c, ldc, init, f),)*
                _ => {
                    for i in i0..m {
                        tile::<T, F, N, P, 1, SIMD>(i, kk, a, b, ldb, c, ldc, init, f);
                    }
                }
            }
        };
    }
    rest!(1 2 3 4 5 6 7);
}

/// Rows `i0..i0+R` of `C`, in column panels of width `P` (`P` divides `N`). With `P = N` the
/// whole `R × N` tile stays in registers while `k` runs and the epilogue sees it there. With
/// `P < N` each panel's `R × P` accumulators stay in registers for the whole `k` loop and are
/// then parked in an `R × N` stack buffer (L1), which the epilogue sees once every panel is done.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn tile<
    T: Real,
    F: FnMut(usize, &mut [T]),
    const N: usize,
    const P: usize,
    const R: usize,
    const SIMD: bool,
>(
    i0: usize,
    kk: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    c: &mut [T],
    ldc: usize,
    init: Init<T>,
    f: &mut F,
) {
    const { assert!(P > 0 && N.is_multiple_of(P)) };
    let mut out = [[T::ZERO; N]; R];
    match init {
        Init::Zero => {}
        Init::Accumulate => {
            for r in 0..R {
                out[r].copy_from_slice(&c[(i0 + r) * ldc..(i0 + r) * ldc + N]);
            }
        }
        Init::Bias(bias) => {
            for r in 0..R {
                out[r].copy_from_slice(&bias[..N]);
            }
        }
    }
    if kk > 0 {
        // One check for the whole tile instead of one per load (they cost as much as the FMAs).
        assert!((i0 + R - 1) * a.rs + (kk - 1) * a.cs < a.data.len());
        assert!((kk - 1) * ldb + N <= b.len());
    }
    if P == N && SIMD && zmm_tile::<T, N, R>(i0, kk, a, b, ldb, &mut out) {
        // Done in explicit AVX-512 registers (`f32` on an AVX-512 build).
    } else if P == N && !(SIMD && ymm_panel::<T, N, P, R>(i0, kk, a, b, ldb, 0, &mut out)) {
        // `out` itself is the register tile.
        for k in 0..kk {
            // SAFETY: `k·ldb + N ≤ b.len()` and `(i0+r)·rs + k·cs < a.len()` by the asserts.
            let brow: &[T; N] = unsafe { &*(b.as_ptr().add(k * ldb) as *const [T; N]) };
            for r in 0..R {
                let x = unsafe { *a.data.get_unchecked((i0 + r) * a.rs + k * a.cs) };
                for j in 0..N {
                    out[r][j] = x.fma(brow[j], out[r][j]);
                }
            }
        }
    } else if P < N {
        for p0 in (0..N).step_by(P) {
            if SIMD && ymm_panel::<T, N, P, R>(i0, kk, a, b, ldb, p0, &mut out) {
                // Done in explicit AVX2 registers (`f32` on an AVX2 + FMA build).
                continue;
            }
            let mut acc = [[T::ZERO; P]; R];
            for r in 0..R {
                acc[r].copy_from_slice(&out[r][p0..p0 + P]);
            }
            for k in 0..kk {
                // SAFETY: `k·ldb + p0 + P ≤ k·ldb + N ≤ b.len()` and
                // `(i0+r)·rs + k·cs < a.len()` by the asserts above.
                let brow: &[T; P] = unsafe { &*(b.as_ptr().add(k * ldb + p0) as *const [T; P]) };
                for r in 0..R {
                    let x = unsafe { *a.data.get_unchecked((i0 + r) * a.rs + k * a.cs) };
                    for j in 0..P {
                        acc[r][j] = x.fma(brow[j], acc[r][j]);
                    }
                }
            }
            for r in 0..R {
                out[r][p0..p0 + P].copy_from_slice(&acc[r]);
            }
        }
    }
    for r in 0..R {
        f(i0 + r, &mut out[r]);
        c[(i0 + r) * ldc..(i0 + r) * ldc + N].copy_from_slice(&out[r]);
    }
}

/// The `R × N` tile of [`tile`] in explicit AVX-512 registers when `T` is `f32` and the build
/// has AVX-512 (`N` = 16, 32, 64: `R·N/16` `zmm` accumulators, at most 24 of the 32, plus the
/// `N/16` vectors of a `B` row and one broadcast); `false` (nothing done) otherwise.
///
/// Why not leave it to the compiler as the portable loop does: LLVM's tuning for Intel's AVX-512
/// cores (Skylake-X to Sapphire Rapids, and what `target-cpu=native` names them) prefers 256-bit
/// vectors (its `prefer-256-bit` tuning flag), so the portable loop's `6 × 64` tile becomes 48
/// `ymm` accumulators and spills, with the fused Softplus epilogue on top: on such a CPU the
/// portable tile ran at under half the 512-bit FMA peak, slower than `matrixmultiply` (measured:
/// docs/benchmarks.md). Intrinsics are 512 bits wide whatever the tuning. Zen 4 (`znver4`) has no
/// such preference: there the portable tile already runs near the peak, and the intrinsics ask
/// for the same operations.
///
/// The sums are the portable loop's, term for term (one fused multiply-add per term, `k` in
/// order), so the results are bit-identical to it (tested).
#[inline(always)]
fn zmm_tile<T: Real, const N: usize, const R: usize>(
    i0: usize,
    kk: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    out: &mut [[T; N]; R],
) -> bool {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    if std::any::TypeId::of::<T>() == std::any::TypeId::of::<f32>()
        && N.is_multiple_of(16)
        && N <= 64
    {
        use std::arch::x86_64::*;
        // SAFETY: `T` is `f32` (same type, so same size and layout); the slices keep their
        // lengths and `out` its shape.
        let (ad, bd, out) = unsafe {
            (
                std::slice::from_raw_parts(a.data.as_ptr().cast::<f32>(), a.data.len()),
                std::slice::from_raw_parts(b.as_ptr().cast::<f32>(), b.len()),
                &mut *(out as *mut [[T; N]; R]).cast::<[[f32; N]; R]>(),
            )
        };
        let v = N / 16;
        // SAFETY: AVX-512F is enabled for the whole build (the `cfg` above). Every load and store
        // stays inside `out` (`16·q + 16 ≤ N`) or inside the extents [`tile`] asserted before
        // calling: `(i0 + r)·rs + k·cs < a.len()` and `k·ldb + N ≤ b.len()` for `k < kk`.
        unsafe {
            let mut acc = [[_mm512_setzero_ps(); 4]; R];
            for r in 0..R {
                for q in 0..v {
                    acc[r][q] = _mm512_loadu_ps(out[r].as_ptr().add(16 * q));
                }
            }
            for k in 0..kk {
                let brow = bd.as_ptr().add(k * ldb);
                let mut bv = [_mm512_setzero_ps(); 4];
                for q in 0..v {
                    bv[q] = _mm512_loadu_ps(brow.add(16 * q));
                }
                for r in 0..R {
                    let x = _mm512_set1_ps(*ad.get_unchecked((i0 + r) * a.rs + k * a.cs));
                    for q in 0..v {
                        acc[r][q] = _mm512_fmadd_ps(x, bv[q], acc[r][q]);
                    }
                }
            }
            for r in 0..R {
                for q in 0..v {
                    _mm512_storeu_ps(out[r].as_mut_ptr().add(16 * q), acc[r][q]);
                }
            }
        }
        return true;
    }
    let _ = (i0, kk, a, b, ldb, out);
    false
}

/// Columns `p0..p0 + 16` of [`tile`]'s `R × N` tile in explicit AVX2 registers when `T` is
/// `f32`, `P` = 16, `R` ≤ 6 and the build has AVX2 and FMA: `2R` `ymm` accumulators (at most 12
/// of the 16), the two `ymm` halves of a `B` row's panel and one broadcast; `false` (nothing
/// done) otherwise. It starts from and ends in `out[r][p0..p0 + 16]`.
///
/// Why not leave it to the compiler: the portable panel loop compiles to slower code on the
/// forward shapes (5–10 % on an Intel Xeon, `x86-64-v3` build; not measured on AMD; measured:
/// docs/benchmarks.md).
///
/// The sums are the portable loop's, term for term (one fused multiply-add per term, `k` in
/// order), so the results are bit-identical to it (tested).
#[inline(always)]
fn ymm_panel<T: Real, const N: usize, const P: usize, const R: usize>(
    i0: usize,
    kk: usize,
    a: Strided<T>,
    b: &[T],
    ldb: usize,
    p0: usize,
    out: &mut [[T; N]; R],
) -> bool {
    #[cfg(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    ))]
    if std::any::TypeId::of::<T>() == std::any::TypeId::of::<f32>() && P == 16 && R <= 6 {
        use std::arch::x86_64::*;
        assert!(p0 + 16 <= N);
        // SAFETY: `T` is `f32` (same type, so same size and layout); the slices keep their
        // lengths and `out` its shape.
        let (ad, bd, out) = unsafe {
            (
                std::slice::from_raw_parts(a.data.as_ptr().cast::<f32>(), a.data.len()),
                std::slice::from_raw_parts(b.as_ptr().cast::<f32>(), b.len()),
                &mut *(out as *mut [[T; N]; R]).cast::<[[f32; N]; R]>(),
            )
        };
        // SAFETY: AVX2 and FMA are enabled for the whole build (the `cfg` above). Every load and
        // store stays inside `out` (`p0 + 16 ≤ N`, asserted) or inside the extents [`tile`]
        // asserted before calling: `(i0 + r)·rs + k·cs < a.len()` and `k·ldb + N ≤ b.len()` for
        // `k < kk`.
        unsafe {
            let mut acc = [[_mm256_setzero_ps(); 2]; R];
            for r in 0..R {
                acc[r][0] = _mm256_loadu_ps(out[r].as_ptr().add(p0));
                acc[r][1] = _mm256_loadu_ps(out[r].as_ptr().add(p0 + 8));
            }
            for k in 0..kk {
                let brow = bd.as_ptr().add(k * ldb + p0);
                let (b0, b1) = (_mm256_loadu_ps(brow), _mm256_loadu_ps(brow.add(8)));
                for r in 0..R {
                    let x = _mm256_set1_ps(*ad.get_unchecked((i0 + r) * a.rs + k * a.cs));
                    acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                    acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                }
            }
            for r in 0..R {
                _mm256_storeu_ps(out[r].as_mut_ptr().add(p0), acc[r][0]);
                _mm256_storeu_ps(out[r].as_mut_ptr().add(p0 + 8), acc[r][1]);
            }
        }
        return true;
    }
    let _ = (i0, kk, a, b, ldb, p0, out);
    false
}

#[cfg(test)]
mod tests;
