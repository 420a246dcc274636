//! Register-blocked matrix products for the MLPs' thin shapes (`[rows × 35] → 64`,
//! `[rows × 64] → 64`, weight gradients summed over thousands of rows).
//!
//! One micro-kernel serves every product: `C[i][0..N] (+)= Σ_k a(i, k) · B[k][0..N]`, where
//! `a(i, k) = A[i·rs + k·cs]` may be strided either way and `B` rows are contiguous. `R` rows of
//! `C` stay in registers (`R × N/16` vectors for `f32` with AVX-512) while `k` runs, each step
//! broadcasting `R` values of `A` against one row of `B`. With `N` fixed at compile time the
//! compiler keeps the accumulators in registers and turns the row loop into vector FMAs; no
//! packing, no allocation. Widths without a specialisation go to [`Real::gemm`]
//! (`matrixmultiply`), which is also the reference the tests compare against.
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
    match n {
        64 => blocks::<T, F, 64, 6>(m, kk, a, b, ldb, c, ldc, init, &mut f),
        32 => blocks::<T, F, 32, 8>(m, kk, a, b, ldb, c, ldc, init, &mut f),
        16 => blocks::<T, F, 16, 8>(m, kk, a, b, ldb, c, ldc, init, &mut f),
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

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn blocks<T: Real, F: FnMut(usize, &mut [T]), const N: usize, const R: usize>(
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
        tile::<T, F, N, R>(i0, kk, a, b, ldb, c, ldc, init, f);
        i0 += R;
    }
    // Remaining rows, as few passes over B as possible.
    let rest = m - i0;
    macro_rules! rest {
        ($($r:literal)*) => {
            match rest {
                0 => {}
                $($r => tile::<T, F, N, $r>(i0, kk, a, b, ldb, c, ldc, init, f),)*
                _ => {
                    for i in i0..m {
                        tile::<T, F, N, 1>(i, kk, a, b, ldb, c, ldc, init, f);
                    }
                }
            }
        };
    }
    rest!(1 2 3 4 5 6 7);
}

/// Rows `i0..i0+R` of `C`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn tile<T: Real, F: FnMut(usize, &mut [T]), const N: usize, const R: usize>(
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
    let mut acc = [[T::ZERO; N]; R];
    match init {
        Init::Zero => {}
        Init::Accumulate => {
            for r in 0..R {
                acc[r].copy_from_slice(&c[(i0 + r) * ldc..(i0 + r) * ldc + N]);
            }
        }
        Init::Bias(bias) => {
            for r in 0..R {
                acc[r].copy_from_slice(&bias[..N]);
            }
        }
    }
    if kk > 0 {
        // One check for the whole tile instead of one per load (they cost as much as the FMAs).
        assert!((i0 + R - 1) * a.rs + (kk - 1) * a.cs < a.data.len());
        assert!((kk - 1) * ldb + N <= b.len());
    }
    for k in 0..kk {
        // SAFETY: `k·ldb + N ≤ b.len()` and `(i0+r)·rs + k·cs < a.len()` by the asserts above.
        let brow: &[T; N] = unsafe { &*(b.as_ptr().add(k * ldb) as *const [T; N]) };
        for r in 0..R {
            let x = unsafe { *a.data.get_unchecked((i0 + r) * a.rs + k * a.cs) };
            for j in 0..N {
                acc[r][j] = x.fma(brow[j], acc[r][j]);
            }
        }
    }
    for r in 0..R {
        f(i0 + r, &mut acc[r]);
        c[(i0 + r) * ldc..(i0 + r) * ldc + N].copy_from_slice(&acc[r]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Every specialised width and the fallback, both operand orientations, accumulate or not,
    /// row counts that leave a remainder, against `matrixmultiply`.
    #[test]
    fn kernels_match_matrixmultiply() {
        let mut rng = Pcg64Mcg::seed_from_u64(31);
        let mut worst = 0.0f64;
        for &(m, kk, n) in &[
            (13usize, 35usize, 64usize),
            (7, 64, 32),
            (35, 100, 64),
            (5, 9, 16),
            (6, 7, 13),
            (1, 1, 64),
            (4, 0, 32),
            (12, 5, 64),
            (11, 3, 32),
        ] {
            for transposed in [false, true] {
                for accumulate in [false, true] {
                    let a: Vec<f64> = (0..m * kk + 1)
                        .map(|_| rng.random_range(-1.0..1.0))
                        .collect();
                    let ldb = n + 3;
                    let b: Vec<f64> = (0..kk * ldb).map(|_| rng.random_range(-1.0..1.0)).collect();
                    let ldc = n + 2;
                    let c0: Vec<f64> = (0..m * ldc).map(|_| rng.random_range(-1.0..1.0)).collect();
                    let sa = if transposed {
                        Strided::transposed(&a[..], m)
                    } else {
                        Strided::row_major(&a[..], kk)
                    };
                    let mut c1 = c0.clone();
                    let mut c2 = c0.clone();
                    let init = if accumulate {
                        Init::Accumulate
                    } else {
                        Init::Zero
                    };
                    gemm(m, kk, n, sa, &b, ldb, &mut c1, ldc, init);
                    gemm_reference(m, kk, n, sa, &b, ldb, &mut c2, ldc, accumulate);
                    for i in 0..m {
                        for j in 0..ldc {
                            let d = (c1[i * ldc + j] - c2[i * ldc + j]).abs();
                            worst = worst.max(d);
                        }
                    }
                }
            }
        }
        assert!(worst < 1e-12, "register kernel vs matrixmultiply: {worst}");
    }
}
