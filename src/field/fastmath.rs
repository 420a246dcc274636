//! Branch-free `f32` approximations of the transcendental functions in the SDF network's hot
//! loop (Softplus on `7·n·64` values per batch), written so the compiler vectorises them, with the
//! `f64` standard-library versions as the reference they are tested against.

/// `a·b + c`, fused where the target has FMA (see [`crate::field::Real::fma`]).
#[inline(always)]
fn fma32(a: f32, b: f32, c: f32) -> f32 {
    crate::field::Real::fma(a, b, c)
}

/// `e^x` for `x ≤ 0` (inputs above 0 are treated as 0; below −87 gives ≈0): Cody–Waite range
/// reduction `x = n·ln2 + r`, `|r| ≤ ln2/2`, degree-6 Taylor polynomial (relative error ≈1e-7),
/// then scaling by `2^n` through the exponent bits.
#[inline(always)]
pub fn exp_nonpos_f32(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    // Not `clamp`: that passes NaN through, and NaN must become a finite value here.
    #[allow(clippy::manual_clamp)]
    let x = x.max(-87.0).min(0.0);
    let n = (x * LOG2E + 0.5).floor();
    let r = x - n * LN2_HI - n * LN2_LO;
    // SAFETY: `x ∈ [−87, 0]` (NaN became −87), so `n ∈ [−126, 0]` fits an i32. (A plain `as`
    // cast would saturate and stop this loop body from vectorising.)
    let n_i = unsafe { n.to_int_unchecked::<i32>() };
    let mut p = 1.0 / 720.0;
    p = fma32(p, r, 1.0 / 120.0);
    p = fma32(p, r, 1.0 / 24.0);
    p = fma32(p, r, 1.0 / 6.0);
    p = fma32(p, r, 0.5);
    p = fma32(p, r, 1.0);
    p = fma32(p, r, 1.0);
    p * f32::from_bits(((n_i + 127) << 23) as u32)
}

/// `ln(1 + u)` for `u ∈ [0, 1]`: `u·P(u)` with `P` the degree-9 least-squares fit of
/// `ln(1+u)/u` at 4000 Chebyshev nodes of `[0, 1]` (fit error 5e-9; relative error of the `f32`
/// evaluation below 2e-7, tested). No division, so it vectorises to ten FMAs.
#[inline(always)]
pub fn ln_1p_unit_f32(u: f32) -> f32 {
    const C: [f32; 10] = [
        1.0,
        -0.499_999_05,
        0.333_300_05,
        -0.249_545_59,
        0.196_781_17,
        -0.153_118_63,
        0.106_142_65,
        -0.057_064_2,
        0.019_907_162,
        -0.003_256_378_5,
    ];
    let mut p = C[9];
    for k in (0..9).rev() {
        p = fma32(p, u, C[k]);
    }
    u * p
}

/// Softplus and its derivative in `f32` (see [`crate::field::Real::softplus_and_grad`]): one
/// exponential, one polynomial, one division, all branch-free so a loop over them vectorises.
#[inline(always)]
pub fn softplus_f32(z: f32, beta: f32) -> (f32, f32) {
    let bz = beta * z;
    // Below e^−60 ≈ 1e-26 the exponential term is flushed to 0: its share of `y` and of the
    // derivative is below f32 resolution next to any O(1e-19) value, and keeping it would feed
    // subnormal numbers (slow, microcode-assisted arithmetic on x86) into the products that
    // follow (`y·W`, `d_h·σ`).
    let t = -bz.abs();
    let e = if t < -60.0 { 0.0 } else { exp_nonpos_f32(t) };
    let y = z.max(0.0) + ln_1p_unit_f32(e) * (1.0 / beta);
    // σ(βz) = 1/(1+e) for βz ≥ 0 and e/(1+e) below (no cancellation either way).
    let r = 1.0 / (1.0 + e);
    (y, if bz >= 0.0 { r } else { e * r })
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
}
