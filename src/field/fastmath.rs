//! Branch-free `f32` approximations of the transcendental functions in the SDF network's hot
//! loop (Softplus on `7·n·64` values per batch), written so the compiler vectorises them, with the
//! `f64` standard-library versions as the reference they are tested against.

/// `e^x` for `x ≤ 0` (inputs above 0 are not supported; below −87 gives ≈0): Cody–Waite range
/// reduction `x = n·ln2 + r`, `|r| ≤ ln2/2`, degree-6 Taylor polynomial (relative error ≈1e-7),
/// then scaling by `2^n` through the exponent bits.
#[inline(always)]
pub fn exp_nonpos_f32(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let x = x.max(-87.0);
    let n = (x * LOG2E + 0.5).floor();
    let r = x - n * LN2_HI - n * LN2_LO;
    let mut p = 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    p = p * r + 1.0;
    p * f32::from_bits(((n as i32 + 127) << 23) as u32)
}

/// `ln(1 + u)` for `u ∈ [0, 1]`: `2·atanh(s)` with `s = u/(2+u) ∈ [0, 1/3]` (no cancellation for
/// small `u`), odd series to `s^13` (relative error ≈1e-8 before rounding).
#[inline(always)]
pub fn ln_1p_unit_f32(u: f32) -> f32 {
    let s = u / (2.0 + u);
    let s2 = s * s;
    let mut p = 1.0 / 13.0;
    p = p * s2 + 1.0 / 11.0;
    p = p * s2 + 1.0 / 9.0;
    p = p * s2 + 1.0 / 7.0;
    p = p * s2 + 1.0 / 5.0;
    p = p * s2 + 1.0 / 3.0;
    p = p * s2 + 1.0;
    2.0 * s * p
}

/// Softplus and its derivative in `f32` (see [`crate::field::Real::softplus_and_grad`]).
#[inline(always)]
pub fn softplus_f32(z: f32, beta: f32) -> (f32, f32) {
    let bz = beta * z;
    let e = exp_nonpos_f32(-bz.abs());
    let y = z.max(0.0) + ln_1p_unit_f32(e) / beta;
    let num = if bz >= 0.0 { 1.0 } else { e };
    (y, num / (1.0 + e))
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
            worst[2] = worst[2].max((y as f64 - yw).abs() / yw.abs().max(1e-30) / k);
            worst[3] = worst[3].max((d as f64 - dw).abs() / dw.abs().max(1e-30) / k);
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
