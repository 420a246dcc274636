// A probe outside the project (issue 14): the forward product [3584 x 35] -> 64 through
// matrixmultiply and hand-written 6 x 16 / 4 x 16 panel variants, one thread, GFLOP/s.
// `same=` compares the whole of C with the crate's product. The variants cover only whole row
// tiles, so R = 6 leaves the last 2 rows (3584 mod 6) as an earlier variant wrote them: `same=`
// is not a check of their sums (the project's kernels are checked by its own tests).

use std::arch::x86_64::*;
use std::hint::black_box;
use std::time::Instant;

fn peak() -> f64 {
    let iters = 20_000_000u64;
    let t = Instant::now();
    unsafe {
        let mut acc = [_mm256_setzero_ps(); 12];
        let a = _mm256_set1_ps(0.999999);
        let b = _mm256_set1_ps(1e-7);
        for _ in 0..iters {
            for v in acc.iter_mut() {
                *v = _mm256_fmadd_ps(*v, a, b);
            }
        }
        black_box(acc);
    }
    (iters * 12 * 8 * 2) as f64 / t.elapsed().as_secs_f64() / 1e9
}

/// current portable panel: R x 16 panels, k loop, broadcasts from A rows
#[inline(never)]
fn panel_portable<const R: usize>(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    const P: usize = 16;
    let mut i0 = 0;
    while i0 + R <= m {
        let mut out = [[0f32; N]; R];
        for p0 in (0..N).step_by(P) {
            let mut acc = [[0f32; P]; R];
            for k in 0..kk {
                let brow: &[f32; P] = unsafe { &*(b.as_ptr().add(k * N + p0) as *const [f32; P]) };
                for r in 0..R {
                    let x = unsafe { *a.get_unchecked((i0 + r) * kk + k) };
                    for j in 0..P {
                        acc[r][j] = x.mul_add(brow[j], acc[r][j]);
                    }
                }
            }
            for r in 0..R {
                out[r][p0..p0 + P].copy_from_slice(&acc[r]);
            }
        }
        for r in 0..R {
            c[(i0 + r) * N..(i0 + r) * N + N].copy_from_slice(&out[r]);
        }
        i0 += R;
    }
}

/// intrinsics: R rows x 16 cols per panel, row pointers, k unrolled by 1, stores straight to C
#[inline(never)]
fn panel_intr<const R: usize>(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    let mut i0 = 0;
    unsafe {
        while i0 + R <= m {
            for p0 in (0..N).step_by(16) {
                let mut acc = [[_mm256_setzero_ps(); 2]; R];
                let mut ap: [*const f32; R] = [std::ptr::null(); R];
                for r in 0..R {
                    ap[r] = a.as_ptr().add((i0 + r) * kk);
                }
                let mut bp = b.as_ptr().add(p0);
                for _ in 0..kk {
                    let b0 = _mm256_loadu_ps(bp);
                    let b1 = _mm256_loadu_ps(bp.add(8));
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*ap[r]);
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                        ap[r] = ap[r].add(1);
                    }
                    bp = bp.add(N);
                }
                for r in 0..R {
                    let cp = c.as_mut_ptr().add((i0 + r) * N + p0);
                    _mm256_storeu_ps(cp, acc[r][0]);
                    _mm256_storeu_ps(cp.add(8), acc[r][1]);
                }
            }
            i0 += R;
        }
    }
}

/// A packed per tile: R x kk -> kk x R contiguous (k-major), so the broadcasts read one stream
#[inline(never)]
fn panel_packed<const R: usize>(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    let mut i0 = 0;
    let mut pa = vec![0f32; kk * R];
    unsafe {
        while i0 + R <= m {
            for k in 0..kk {
                for r in 0..R {
                    pa[k * R + r] = a[(i0 + r) * kk + k];
                }
            }
            for p0 in (0..N).step_by(16) {
                let mut acc = [[_mm256_setzero_ps(); 2]; R];
                let mut app = pa.as_ptr();
                let mut bp = b.as_ptr().add(p0);
                for _ in 0..kk {
                    let b0 = _mm256_loadu_ps(bp);
                    let b1 = _mm256_loadu_ps(bp.add(8));
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*app.add(r));
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                    }
                    app = app.add(R);
                    bp = bp.add(N);
                }
                for r in 0..R {
                    let cp = c.as_mut_ptr().add((i0 + r) * N + p0);
                    _mm256_storeu_ps(cp, acc[r][0]);
                    _mm256_storeu_ps(cp.add(8), acc[r][1]);
                }
            }
            i0 += R;
        }
    }
}

/// 4 rows x 24 ... no: R rows x 32 cols? needs R*4 acc; R=3 -> 12 acc + 4 b + 1 = 17 (spill). skip.

/// intrinsics, k unrolled by 2
#[inline(never)]
fn panel_intr2<const R: usize>(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    let mut i0 = 0;
    unsafe {
        while i0 + R <= m {
            let base = a.as_ptr().add(i0 * kk);
            for p0 in (0..N).step_by(16) {
                let mut acc = [[_mm256_setzero_ps(); 2]; R];
                let mut bp = b.as_ptr().add(p0);
                let mut k = 0;
                while k + 2 <= kk {
                    let b0 = _mm256_loadu_ps(bp);
                    let b1 = _mm256_loadu_ps(bp.add(8));
                    let b2 = _mm256_loadu_ps(bp.add(N));
                    let b3 = _mm256_loadu_ps(bp.add(N + 8));
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*base.add(r * kk + k));
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                    }
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*base.add(r * kk + k + 1));
                        acc[r][0] = _mm256_fmadd_ps(x, b2, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b3, acc[r][1]);
                    }
                    bp = bp.add(2 * N);
                    k += 2;
                }
                if k < kk {
                    let b0 = _mm256_loadu_ps(bp);
                    let b1 = _mm256_loadu_ps(bp.add(8));
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*base.add(r * kk + k));
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                    }
                }
                for r in 0..R {
                    let cp = c.as_mut_ptr().add((i0 + r) * N + p0);
                    _mm256_storeu_ps(cp, acc[r][0]);
                    _mm256_storeu_ps(cp.add(8), acc[r][1]);
                }
            }
            i0 += R;
        }
    }
}

/// B-stationary: for each 16-col panel, stream all row tiles (B panel 35x16 stays hot)
#[inline(never)]
fn panel_bstat<const R: usize>(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    unsafe {
        for p0 in (0..N).step_by(16) {
            let mut i0 = 0;
            while i0 + R <= m {
                let base = a.as_ptr().add(i0 * kk);
                let mut acc = [[_mm256_setzero_ps(); 2]; R];
                let mut bp = b.as_ptr().add(p0);
                for k in 0..kk {
                    let b0 = _mm256_loadu_ps(bp);
                    let b1 = _mm256_loadu_ps(bp.add(8));
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*base.add(r * kk + k));
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                    }
                    bp = bp.add(N);
                }
                for r in 0..R {
                    let cp = c.as_mut_ptr().add((i0 + r) * N + p0);
                    _mm256_storeu_ps(cp, acc[r][0]);
                    _mm256_storeu_ps(cp.add(8), acc[r][1]);
                }
                i0 += R;
            }
        }
    }
}

fn main() {
    let (m, kk, n) = (3584usize, 35usize, 64usize);
    let a: Vec<f32> = (0..m * kk).map(|i| ((i * 7919) % 1000) as f32 / 1000.0 - 0.5).collect();
    let b: Vec<f32> = (0..kk * n).map(|i| ((i * 104729) % 1000) as f32 / 1000.0 - 0.5).collect();
    let mut c = vec![0f32; m * n];
    let mut c2 = vec![0f32; m * n];
    let flops = 2.0 * (m * kk * n) as f64;
    let reps = 400;
    let time = |f: &mut dyn FnMut()| -> f64 {
        let mut best = f64::MAX;
        for _ in 0..5 {
            let t = Instant::now();
            for _ in 0..reps { f(); }
            best = best.min(t.elapsed().as_secs_f64());
        }
        flops * reps as f64 / best / 1e9
    };
    println!("single-thread ymm FMA peak: {:.1} GFLOP/s", peak());
    let g = time(&mut || unsafe { matrixmultiply::sgemm(m, kk, n, 1.0, a.as_ptr(), kk as isize, 1, b.as_ptr(), n as isize, 1, 0.0, c2.as_mut_ptr(), n as isize, 1) });
    println!("matrixmultiply {g:.1}");
    let g = time(&mut || panel_portable::<6>(m, kk, &a, &b, &mut c)); println!("portable R6 {g:.1} same={}", c == c2);
    let g = time(&mut || panel_intr::<6>(m, kk, &a, &b, &mut c)); println!("intr R6 {g:.1} same={}", c == c2);
    let g = time(&mut || panel_intr::<4>(m, kk, &a, &b, &mut c)); println!("intr R4 {g:.1}");
    let g = time(&mut || panel_packed::<6>(m, kk, &a, &b, &mut c)); println!("packed R6 {g:.1} same={}", c == c2);
    let g = time(&mut || panel_packed::<4>(m, kk, &a, &b, &mut c)); println!("packed R4 {g:.1}");
    let g = time(&mut || panel_intr2::<6>(m, kk, &a, &b, &mut c)); println!("intr2 R6 {g:.1}");
    let g = time(&mut || panel_bstat::<6>(m, kk, &a, &b, &mut c)); println!("bstat R6 {g:.1}");
    let g = time(&mut || unsafe { matrixmultiply::sgemm(m, kk, n, 1.0, a.as_ptr(), kk as isize, 1, b.as_ptr(), n as isize, 1, 0.0, c2.as_mut_ptr(), n as isize, 1) });
    println!("matrixmultiply {g:.1}");
    println!("single-thread ymm FMA peak: {:.1} GFLOP/s", peak());
}
