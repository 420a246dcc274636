// A probe outside the project (issue 14, 2026-11-26): the forward product [3584 x 35] -> 64,
// one thread, GFLOP/s, through matrixmultiply and hand-written panel variants. Built twice
// (`run.sh`): plainly, where matrixmultiply picks its AVX-512 kernel on this AVX-512 CPU, and
// with MMTEST_FEATURE=avx,avx2,fma, which holds the crate to the AVX2 + FMA kernel that
// AVX2-only CPUs run. Also: FMA chain peaks with 8/10/12/14 independent chains; the panel
// variants with B and C at 0/16/32-byte offsets from a cache line (split loads are not the
// cause); `u4` (6 x 16, k unrolled by 4, two row bases and a stride); `mm8` (the crate's 8 x 8
// outer-product shape with A packed per row block, scalar scatter of C, for timing only).
// `same=` / `maxdiff=` compare C with the crate's product (the panels cover whole row tiles
// only: 3584 mod 6 leaves 2 rows, which `same=` skips).

use std::arch::x86_64::*;
use std::hint::black_box;
use std::time::Instant;

fn peakn<const C: usize>() -> f64 {
    let iters = 20_000_000u64;
    let t = Instant::now();
    unsafe {
        let mut acc = [_mm256_setzero_ps(); C];
        let a = _mm256_set1_ps(0.999999);
        let b = _mm256_set1_ps(1e-7);
        for _ in 0..iters {
            for v in acc.iter_mut() {
                *v = _mm256_fmadd_ps(*v, a, b);
            }
        }
        black_box(acc);
    }
    (iters * C as u64 * 8 * 2) as f64 / t.elapsed().as_secs_f64() / 1e9
}
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



/// 6 x 16 panels, k unrolled by 4, rows addressed from two bases and a byte stride
#[inline(never)]
fn panel_u4(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32]) {
    const N: usize = 64;
    const R: usize = 6;
    let mut i0 = 0;
    unsafe {
        while i0 + R <= m {
            for p0 in (0..N).step_by(16) {
                let mut acc = [[_mm256_setzero_ps(); 2]; R];
                let p = a.as_ptr().add(i0 * kk);
                let q = p.add(3 * kk);
                let s = kk;
                let mut bp = b.as_ptr().add(p0);
                let mut k = 0;
                macro_rules! step { ($o:expr) => {{
                    let b0 = _mm256_loadu_ps(bp.add($o * N));
                    let b1 = _mm256_loadu_ps(bp.add($o * N + 8));
                    let xs = [p.add(k + $o), p.add(s + k + $o), p.add(2 * s + k + $o), q.add(k + $o), q.add(s + k + $o), q.add(2 * s + k + $o)];
                    for r in 0..R {
                        let x = _mm256_broadcast_ss(&*xs[r]);
                        acc[r][0] = _mm256_fmadd_ps(x, b0, acc[r][0]);
                        acc[r][1] = _mm256_fmadd_ps(x, b1, acc[r][1]);
                    }
                }}}
                while k + 4 <= kk {
                    step!(0); step!(1); step!(2); step!(3);
                    bp = bp.add(4 * N);
                    k += 4;
                }
                while k < kk { step!(0); bp = bp.add(N); k += 1; }
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

/// matrixmultiply-style 8 x 8 outer products: A packed k-major per 8-row block (once per block,
/// used by all 8 column panels), permutes of A against 128-bit broadcasts of B
#[inline(never)]
fn panel_mm8(m: usize, kk: usize, a: &[f32], b: &[f32], c: &mut [f32], pa: &mut Vec<f32>) {
    const N: usize = 64;
    pa.resize(kk * 8, 0.0);
    let mut i0 = 0;
    unsafe {
        while i0 + 8 <= m {
            // pack: 8 rows x kk -> kk x 8
            let ab = a.as_ptr().add(i0 * kk);
            let pp = pa.as_mut_ptr();
            for k in 0..kk { for r in 0..8 { *pp.add(k * 8 + r) = *ab.add(r * kk + k); } }
            for p0 in (0..N).step_by(8) {
                let mut ab8 = [_mm256_setzero_ps(); 8];
                let mut ap = pa.as_ptr();
                let mut bp = b.as_ptr().add(p0);
                for _ in 0..kk {
                    let av = _mm256_loadu_ps(ap);
                    let bl = _mm256_broadcast_ps(&*(bp as *const __m128));
                    let bh = _mm256_broadcast_ps(&*(bp.add(4) as *const __m128));
                    let a1 = _mm256_permute_ps(av, 0b00_11_10_01);
                    let a2 = _mm256_permute_ps(av, 0b01_00_11_10);
                    let a3 = _mm256_permute_ps(av, 0b10_01_00_11);
                    ab8[0] = _mm256_fmadd_ps(av, bl, ab8[0]); ab8[4] = _mm256_fmadd_ps(av, bh, ab8[4]);
                    ab8[1] = _mm256_fmadd_ps(a1, bl, ab8[1]); ab8[5] = _mm256_fmadd_ps(a1, bh, ab8[5]);
                    ab8[2] = _mm256_fmadd_ps(a2, bl, ab8[2]); ab8[6] = _mm256_fmadd_ps(a2, bh, ab8[6]);
                    ab8[3] = _mm256_fmadd_ps(a3, bl, ab8[3]); ab8[7] = _mm256_fmadd_ps(a3, bh, ab8[7]);
                    ap = ap.add(8);
                    bp = bp.add(N);
                }
                // scatter (slow, scalar; timing only)
                let mut t = [[0f32; 8]; 8];
                for q in 0..8 { _mm256_storeu_ps(t[q].as_mut_ptr(), ab8[q]); }
                let cp = c.as_mut_ptr().add(i0 * N + p0);
                for q in 0..4 { for l in 0..8 {
                    // ab8[q][l] = a[(l & 4) + ((l + q) & 3)] * b[l & 3] (bl) ; ab8[q+4][l] = a[..] * b[4 + (l&3)]
                    let row = (l & 4) + ((l + q) & 3);
                    *cp.add(row * N + (l & 3)) = t[q][l];
                    *cp.add(row * N + 4 + (l & 3)) = t[q + 4][l];
                }}
            }
            i0 += 8;
        }
    }
}
fn aligned(v: &[f32], off: usize) -> (Vec<f32>, usize) {
    let mut buf = vec![0f32; v.len() + 64];
    let addr = buf.as_ptr() as usize;
    let mis = (addr / 4) % 16;
    let start = (16 - mis) % 16 + off / 4;
    buf[start..start + v.len()].copy_from_slice(v);
    (buf, start)
}

fn main() {
    let (m, kk, n) = (3584usize, 35usize, 64usize);
    let a0: Vec<f32> = (0..m * kk).map(|i| ((i * 7919) % 1000) as f32 / 1000.0 - 0.5).collect();
    let b0: Vec<f32> = (0..kk * n).map(|i| ((i * 104729) % 1000) as f32 / 1000.0 - 0.5).collect();
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
    println!("peaks 8/10/12/14: {:.1} {:.1} {:.1} {:.1}", peakn::<8>(), peakn::<10>(), peakn::<12>(), peakn::<14>());
    for boff in [0usize, 16, 32] {
      for coff in [0usize, 16] {
        let (bb, bs) = aligned(&b0, boff);
        let b = &bb[bs..bs + b0.len()];
        let (aa, as_) = aligned(&a0, 0);
        let a = &aa[as_..as_ + a0.len()];
        let (mut cc, cs) = aligned(&vec![0f32; m * n], coff);
        let (mut cc2, cs2) = aligned(&vec![0f32; m * n], coff);
        let c = &mut cc[cs..cs + m * n];
        let c2 = &mut cc2[cs2..cs2 + m * n];
        println!("-- B offset {boff} bytes from a line, C offset {coff}");
        let g = time(&mut || unsafe { matrixmultiply::sgemm(m, kk, n, 1.0, a.as_ptr(), kk as isize, 1, b.as_ptr(), n as isize, 1, 0.0, c2.as_mut_ptr(), n as isize, 1) });
        println!("matrixmultiply {g:.1}");
        let g = time(&mut || panel_portable::<6>(m, kk, a, b, c)); println!("portable R6 {g:.1}");
        let g = time(&mut || panel_intr::<6>(m, kk, a, b, c)); println!("intr R6 {g:.1}");
        let g = time(&mut || panel_intr2::<6>(m, kk, a, b, c)); println!("intr2 R6 {g:.1}");
        let g = time(&mut || panel_u4(m, kk, a, b, c)); println!("u4 R6 {g:.1} same={}", c[..3582*64] == c2[..3582*64]);
        let mut pa = Vec::new();
        let g = time(&mut || panel_mm8(m, kk, a, b, c, &mut pa)); println!("mm8 {g:.1} maxdiff={}", c.iter().zip(c2.iter()).map(|(x,y)|(x-y).abs()).fold(0f32,f32::max));
      }
    }
}
