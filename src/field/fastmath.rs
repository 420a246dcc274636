//! Branch-free `f32` approximations of the transcendental functions in the SDF network's hot
//! loop (Softplus on `7·n·64` values per batch), written so the compiler vectorises them, with the
//! `f64` standard-library versions as the reference they are tested against. Polynomials are
//! Chebyshev fits (mpmath `chebyfit`, near-minimax) of the lowest degree that keeps the stated
//! bounds, evaluated in Estrin form (short dependency chains), and the exponential's range
//! reduction uses the float-add rounding trick instead of `floor` + conversion. This made Softplus
//! alone 1.2–1.45× faster (`benches/field.rs`, AVX2 and AVX-512 builds).

/// `a·b + c`, fused where the target has FMA (see [`crate::field::Real::fma`]).
#[inline(always)]
fn fma32(a: f32, b: f32, c: f32) -> f32 {
    crate::field::Real::fma(a, b, c)
}

/// `e^x` for `x ≤ 0` (inputs above 0 are treated as 0, NaN and anything below −87 as −87, which
/// gives ≈1.6e-38): `e^x = 2^{−n}·2^f` with `n = round(−x·log₂e)` (the float-add rounding trick,
/// no conversion instruction), `f = n + x·log₂e ∈ [−½, ½]` ([`reduced_exponent`], so `f` is
/// accurate to 5e-8 even at `x = −87`), `2^f` a degree-5 polynomial (Chebyshev fit on
/// `[−½, ½]`, fit error 7.9e-8) in Estrin form (three FMA levels instead of five), and `2^{−n}`
/// put into the exponent bits. Relative error below 5e-7 on `[−87, 0]` (tested; ≈2e-7 seen).
#[inline(always)]
pub fn exp_nonpos_f32(x: f32) -> f32 {
    // 1.5·2²³: adding it to a value in [0, 2²²) rounds that value to an integer, which lands in
    // the low mantissa bits of the sum.
    const ROUND: f32 = 12_582_912.0;
    const C: [f32; 6] = [
        1.000_000_1,
        std::f32::consts::LN_2, // the fit's coefficient rounds to it
        0.240_221_07,
        0.055_503_57,
        0.009_676_032,
        0.001_339_086_3,
    ];
    // Not `clamp`: that passes NaN through, and NaN must become a finite value here.
    #[allow(clippy::manual_clamp)]
    let t = -(x.max(-87.0).min(0.0));
    let shifted = fma32(t, LOG2E_HI, ROUND);
    let n = shifted - ROUND;
    let f = reduced_exponent(t, n);
    let f2 = f * f;
    let p = fma32(
        fma32(fma32(C[5], f, C[4]), f2, fma32(C[3], f, C[2])),
        f2,
        fma32(C[1], f, C[0]),
    );
    // 2^{−n} with n ∈ [0, 126]: exponent field 127 − n. The integer n sits in the low bits of
    // `shifted`; shifting them into the exponent field drops the rest.
    let scale = f32::from_bits((127u32 << 23).wrapping_sub(shifted.to_bits() << 23));
    p * scale
}

/// The `f32` rounding of log₂e; [`LOG2E_LO`] is the rest.
const LOG2E_HI: f32 = std::f32::consts::LOG2_E;
const LOG2E_LO: f32 = 1.925_963e-8;

/// `f = n − t·log₂e` for `t ∈ [0, 87]` and the integer `n = round(t·log₂e)` (so `|f| ≲ ½`), to
/// within 5e-8 absolute (tested: 3.0e-8 with FMA, 4.4e-8 without). With FMA
/// ([`crate::field::HAS_FMA`]) the product of the two-part `log₂e = hi + lo` is taken exactly by
/// the fused operations. Without it (x86-64 below v3) that product would be rounded (absolute
/// error up to `87·log₂e·6e-8 ≈ 7.5e-6` in `f`, 3e-6 relative in `e^x`, found by the x86-64-v2
/// run of `scripts/portable_check.sh`), so [`reduced_exponent_cody_waite`] is used there.
#[inline(always)]
fn reduced_exponent(t: f32, n: f32) -> f32 {
    if crate::field::HAS_FMA {
        fma32(-t, LOG2E_LO, fma32(-t, LOG2E_HI, n))
    } else {
        reduced_exponent_cody_waite(t, n)
    }
}

/// [`reduced_exponent`] without fused operations: Cody–Waite's reduction in the natural base
/// (Cody & Waite, *Software Manual for the Elementary Functions*, 1980, ch. 6),
/// `r = t − n·ln2` with `ln2 = C1 + C2`, `C1 = 355/512` having 9 significant bits, so `n·C1`
/// (`n ≤ 126`) is exact and so is, nearly always, `t − n·C1`; then `f = −r·log₂e` with one
/// rounding. Tested on every build against `f64`.
#[inline(always)]
fn reduced_exponent_cody_waite(t: f32, n: f32) -> f32 {
    const LN2_C1: f32 = 0.693_359_4; // 355/512
    const LN2_C2: f32 = -2.121_944_4e-4; // ln 2 − 355/512
    let r = (t - n * LN2_C1) - n * LN2_C2;
    -r * LOG2E_HI
}

/// `ln(1 + u)` for `u ∈ [0, 1]`: `u·P(u)` with `P` the degree-8 Chebyshev fit of `ln(1+u)/u`
/// on `[0, 1]` (fit error 3.3e-8; relative error of the `f32` evaluation below 2e-7, tested),
/// evaluated in Estrin form (four FMA levels instead of eight). No division, so it vectorises.
#[inline(always)]
pub fn ln_1p_unit_f32(u: f32) -> f32 {
    u * ln_1p_ratio_f32(u)
}

/// `ln(1 + u)/u` for `u ∈ [0, 1]` (the polynomial `P` of [`ln_1p_unit_f32`]; `P(0) = 1 − 6e-8`).
#[inline(always)]
pub fn ln_1p_ratio_f32(u: f32) -> f32 {
    const C: [f32; 9] = [
        0.999_999_94,
        -0.499_994_46,
        0.333_181_2,
        -0.248_353_99,
        0.190_768_81,
        -0.136_022_48,
        0.077_516_09,
        -0.029_074_065,
        0.005_126_102_4,
    ];
    let u2 = u * u;
    let u4 = u2 * u2;
    let lo = fma32(fma32(C[3], u, C[2]), u2, fma32(C[1], u, C[0]));
    let hi = fma32(fma32(C[7], u, C[6]), u2, fma32(C[5], u, C[4]));
    fma32(fma32(C[8], u4, hi), u4, lo)
}

/// Largest error of [`softplus_f32`] against the exact softplus of its `f32` input, as a fraction
/// of `(1 + β|z|)·|exact|`, for both outputs (tested over the whole `f32` range for β = 1, 3,
/// 100, 1000; 2.7e-7 is the worst seen): the `1 + β|z|` is the conditioning of `e^{−β|z|}`
/// (rounding `z` to `f32` alone moves it by `β|z|·6e-8`). Where `β|z| ≥ 60` (in `f32`) the
/// exponential term is flushed instead: an absolute error below [`SOFTPLUS_FLUSH_ABS`]`/β` on `y`
/// and [`SOFTPLUS_FLUSH_ABS`] on `σ`.
pub const SOFTPLUS_MAX_REL_ERROR: f64 = 4e-7;

/// Absolute error bound of the flushed exponential term, `e^{−60}` (see
/// [`SOFTPLUS_MAX_REL_ERROR`]).
pub const SOFTPLUS_FLUSH_ABS: f64 = 8.8e-27;

/// Softplus `y = ln(1 + e^{βz})/β` and its derivative `σ(βz)` in `f32` (see
/// [`crate::field::Real::softplus_and_grad`]), within [`SOFTPLUS_MAX_REL_ERROR`] of the exact
/// values: `y = max(z, 0) + ln(1 + u)/β` and `σ = (1 or u)/(1 + u)` from one exponential
/// `u = e^{−β|z|} ∈ (0, 1]` shared by both (the derivative costs one division more), all
/// branch-free so a loop over them vectorises (≈35 vector operations per 8 or 16 values).
/// Finite for every finite `z` (`β|z|` may overflow to ∞: then `u = 0`, `y = max(z, 0)`).
#[inline(always)]
pub fn softplus_f32(z: f32, beta: f32) -> (f32, f32) {
    let bz = beta * z;
    // Below e^−60 ≈ 1e-26 the exponential term is flushed to 0: its share of `y` and of the
    // derivative is below f32 resolution next to any O(1e-19) value, and keeping it would feed
    // subnormal numbers (slow, microcode-assisted arithmetic on x86) into the products that
    // follow (`y·W`, `d_h·σ`).
    let t = bz.abs();
    let u = if t < 60.0 { exp_nonpos_f32(-t) } else { 0.0 };
    // ln(1+u) = u·P(u) with P(u) = ln(1+u)/u; below u ≈ 1.1e-7 (t ≥ 16) P(u) is evaluated at 0
    // (P(0) = 1 − 6e-8 against the exact 1 − u/2: relative error below 1.2e-7), because the
    // powers u², u⁴ of the polynomial are subnormal for t in (21.8, 25.8) and (43.7, 51.6):
    // an x86-64-v3 build on an Intel Xeon spent 6× longer in this function than on Zen 4 for
    // that (microcode assists on subnormal operands; AMD handles them in hardware).
    let u_poly = if t < 16.0 { u } else { 0.0 };
    let y = fma32(u * ln_1p_ratio_f32(u_poly), 1.0 / beta, z.max(0.0));
    // σ(βz) = 1/(1+u) for βz ≥ 0 and u/(1+u) below (no cancellation either way).
    let r = 1.0 / (1.0 + u);
    (y, if bz >= 0.0 { r } else { u * r })
}

/// Reference softplus and derivative in `f64` with the standard library.
#[inline(always)]
pub fn softplus_f64(z: f64, beta: f64) -> (f64, f64) {
    let bz = beta * z;
    let e = (-bz.abs()).exp();
    let y = z.max(0.0) + e.ln_1p() / beta;
    let num = if bz >= 0.0 { 1.0 } else { e };
    (y, num / (1.0 + e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_functions_match_std() {
        let mut worst = [0f64; 4];
        for i in 0..=200_000 {
            let x = -88.0 * i as f64 / 200_000.0;
            let e = exp_nonpos_f32(x as f32) as f64;
            let want = (x as f32 as f64).exp();
            if want > 1e-37 {
                worst[0] = worst[0].max(((e - want) / want).abs());
            }
            let u = i as f64 / 200_000.0;
            let l = ln_1p_unit_f32(u as f32) as f64;
            let want = (u as f32 as f64).ln_1p();
            if u > 0.0 {
                worst[1] = worst[1].max(((l - want) / want).abs());
            }
            let z = (i as f64 - 100_000.0) * 1e-4;
            let (y, d) = softplus_f32(z as f32, 100.0);
            let (yw, dw) = softplus_f64(z as f32 as f64, 100.0);
            // f32 rounding of βz alone costs |βz|·6e-8 relative in e^{−|βz|}: scale by it.
            let k = 1.0 + 100.0 * z.abs();
            if 100.0 * z.abs() > 59.9 {
                // The exponential term (< e^−60 ≈ 8.8e-27) is flushed to zero by design: an
                // absolute error below 1e-26 (scaled into the same 5e-7 bound).
                worst[2] = worst[2].max((y as f64 - yw).abs() / (k * yw.abs()).max(2e-20));
                worst[3] = worst[3].max((d as f64 - dw).abs() / (k * dw.abs()).max(2e-20));
            } else {
                worst[2] = worst[2].max((y as f64 - yw).abs() / yw.abs().max(1e-30) / k);
                worst[3] = worst[3].max((d as f64 - dw).abs() / dw.abs().max(1e-30) / k);
            }
        }
        assert!(
            worst.iter().all(|&w| w < 5e-7),
            "relative errors exp, ln1p, softplus, σ: {worst:?}"
        );
        // PyTorch's threshold form agrees: above βz = 20 softplus is z.
        assert!((softplus_f64(0.5, 100.0).0 - 0.5).abs() < 1e-20);
        assert!(softplus_f32(-10.0, 100.0).0 < 1e-37);
    }

    /// Both range reductions of [`exp_nonpos_f32`] against `f64` over `t ∈ [0, 87]`: the one
    /// this build uses and the Cody–Waite one of builds without FMA, which is thus tested on
    /// every build (the x86-64-v2 run of `scripts/portable_check.sh` tests it in place).
    #[test]
    fn range_reductions_are_accurate_with_and_without_fma() {
        let mut worst = [0f64; 2];
        for i in 0..=870_000 {
            let t = (i as f64 * 1e-4) as f32;
            let shifted = t * LOG2E_HI + 12_582_912.0;
            let n = shifted - 12_582_912.0;
            let want = n as f64 - t as f64 * std::f64::consts::LOG2_E;
            assert!(want.abs() < 0.51, "t {t}: n {n} is not round(t·log₂e)");
            worst[0] = worst[0].max((reduced_exponent(t, n) as f64 - want).abs());
            worst[1] = worst[1].max((reduced_exponent_cody_waite(t, n) as f64 - want).abs());
        }
        assert!(
            worst.iter().all(|&w| w < 5e-8),
            "absolute errors of f (this build, Cody–Waite): {worst:?}"
        );
    }

    /// [`softplus_f32`] against the `f64` standard-library softplus of the same `f32` input over
    /// the whole range of `f32` (both signs, |z| from 1e-12 to `f32::MAX`, β = 100 as the SDF
    /// uses and others), with the stated bound [`SOFTPLUS_MAX_REL_ERROR`] /
    /// [`SOFTPLUS_FLUSH_ABS`]; plus the saturated regions exactly: `y = z` above βz = 20
    /// (PyTorch's threshold form), `σ = 1` above βz = 17, `y = σ = 0` where the exponential is
    /// flushed below zero, and finite outputs for every finite input.
    #[test]
    fn softplus_error_bound_over_the_whole_range() {
        let mut zs: Vec<f32> = vec![0.0, -0.0, f32::MAX, f32::MIN, f32::MIN_POSITIVE, 1e-45];
        // Logarithmic sweep of |z| from 1e-12 to 3e38, 4000 points per decade, both signs.
        for i in 0..=50 * 4000 {
            let m = 10f64.powf(-12.0 + i as f64 / 4000.0);
            if m < f32::MAX as f64 {
                zs.push(m as f32);
                zs.push(-(m as f32));
            }
        }
        // Dense linear sweep around the kink, where the output is O(1/β).
        for i in -200_000..=200_000 {
            zs.push(i as f32 * 1e-6);
        }
        for beta in [100.0f32, 1.0, 3.0, 1000.0] {
            let mut worst = (0.0f64, 0.0f32);
            for &z in &zs {
                let (y, d) = softplus_f32(z, beta);
                assert!(y.is_finite() && d.is_finite(), "β={beta} z={z}: ({y}, {d})");
                assert!(
                    y >= 0.0 && (0.0..=1.0).contains(&d),
                    "β={beta} z={z}: ({y}, {d})"
                );
                let (zz, b) = (z as f64, beta as f64);
                let (yw, dw) = softplus_f64(zz, b);
                let bz = b * zz;
                let k = 1.0 + bz.abs();
                // The flush rule as the function applies it, on the `f32` product.
                let flushed = (beta * z).abs() >= 60.0;
                let flush = if flushed { SOFTPLUS_FLUSH_ABS } else { 0.0 };
                let ey = (y as f64 - yw).abs() / (SOFTPLUS_MAX_REL_ERROR * k * yw + flush / b);
                let ed = (d as f64 - dw).abs() / (SOFTPLUS_MAX_REL_ERROR * k * dw + flush);
                for e in [ey, ed] {
                    if e > worst.0 {
                        worst = (e, z);
                    }
                }
                if bz > 20.0 {
                    assert_eq!(y, z, "β={beta}: saturation above βz = 20");
                }
                if bz > 17.0 {
                    assert_eq!(d, 1.0, "β={beta} z={z}: σ saturates to 1");
                }
                if flushed && z < 0.0 {
                    assert!(
                        y == 0.0 && d == 0.0,
                        "β={beta} z={z}: flushed to ({y}, {d})"
                    );
                }
            }
            assert!(
                worst.0 <= 1.0,
                "β={beta}: error {:.3} × the stated bound at z = {:e}",
                worst.0,
                worst.1
            );
        }
    }

    /// No subnormal number enters or leaves any operation of [`softplus_f32`] for inputs whose
    /// outputs are normal: the x86 MXCSR sticky flags DE (a subnormal operand, bit 1) and UE
    /// (a result that underflowed, bit 4) stay clear over a sweep of βz ∈ [−80, 80] at β = 100,
    /// the range where the former polynomial squared `u = e^{−β|z|}` into subnormals (6× slower
    /// on an Intel Xeon, microcode assists). Inputs go through `black_box` so nothing is folded.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(deprecated)] // _mm_getcsr / _mm_setcsr: the only stable way to read the flags
    fn softplus_feeds_no_subnormal_numbers() {
        use std::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        const DE: u32 = 1 << 1;
        const UE: u32 = 1 << 4;
        let beta = 100.0f32;
        let zs: Vec<f32> = (-80_000..=80_000).map(|i| i as f32 * 1e-5).collect();
        // SAFETY: only the sticky exception flags (bits 0–5) are cleared; the rounding mode and
        // the masks stay as they are.
        unsafe { _mm_setcsr(_mm_getcsr() & !0x3f) };
        let mut acc = 0.0f32;
        for &z in &zs {
            let (y, s) = softplus_f32(std::hint::black_box(z), std::hint::black_box(beta));
            acc += std::hint::black_box(y) * 0.0 + std::hint::black_box(s) * 0.0;
        }
        let flags = unsafe { _mm_getcsr() };
        assert_eq!(acc, 0.0);
        assert_eq!(
            flags & (DE | UE),
            0,
            "MXCSR flags {flags:#x}: a subnormal was produced or used"
        );
    }
}
