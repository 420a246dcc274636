//! Image quality of held-out renders: PSNR and SSIM on `[0, 1]` RGB.

use crate::scene::RgbImage;

/// Peak signal-to-noise ratio in dB for values in `[0, 1]`: `-10·log10(MSE)`. Identical images
/// give `+inf`; mismatched sizes panic (a programming error, not user input).
pub fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "PSNR of images of different sizes"
    );
    let mse = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| ((x - y) as f64).powi(2))
        .sum::<f64>()
        / a.data.len().max(1) as f64;
    psnr_from_mse(mse)
}

/// `-10·log10(mse)` (`+inf` for 0).
pub fn psnr_from_mse(mse: f64) -> f64 {
    -10.0 * mse.log10()
}

/// Structural similarity (Wang et al. 2004) with the usual settings: an 11×11 Gaussian window
/// with σ = 1.5, `K1 = 0.01`, `K2 = 0.03`, data range 1, computed per channel over the valid
/// (un-padded) window positions and averaged — the definition of scikit-image's
/// `structural_similarity(..., gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
/// data_range=1)`, except that we drop the border instead of reflecting it. Images smaller than
/// the window give `None`.
pub fn ssim(a: &RgbImage, b: &RgbImage) -> Option<f64> {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "SSIM of images of different sizes"
    );
    const R: usize = 5;
    const N: usize = 2 * R + 1;
    let (w, h) = (a.width, a.height);
    if w < N || h < N {
        return None;
    }
    let g: Vec<f64> = (0..N)
        .map(|i| (-((i as f64 - R as f64).powi(2)) / (2.0 * 1.5 * 1.5)).exp())
        .collect();
    let gs: f64 = g.iter().sum();
    let g: Vec<f64> = g.iter().map(|v| v / gs).collect();
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let mut total = 0.0;
    let mut count = 0usize;
    for c in 0..3 {
        let px = |img: &RgbImage, x: usize, y: usize| img.data[(y * w + x) * 3 + c] as f64;
        // Separable filtering of x, y, x², y², xy: horizontal pass then vertical pass.
        let mut horiz = vec![[0.0f64; 5]; (w - N + 1) * h];
        for y in 0..h {
            for x in 0..=w - N {
                let mut acc = [0.0; 5];
                for (k, gk) in g.iter().enumerate() {
                    let (p, q) = (px(a, x + k, y), px(b, x + k, y));
                    acc[0] += gk * p;
                    acc[1] += gk * q;
                    acc[2] += gk * p * p;
                    acc[3] += gk * q * q;
                    acc[4] += gk * p * q;
                }
                horiz[y * (w - N + 1) + x] = acc;
            }
        }
        for y in 0..=h - N {
            for x in 0..=w - N {
                let mut m = [0.0; 5];
                for (k, gk) in g.iter().enumerate() {
                    let v = horiz[(y + k) * (w - N + 1) + x];
                    for i in 0..5 {
                        m[i] += gk * v[i];
                    }
                }
                let (mx, my) = (m[0], m[1]);
                let (vx, vy, cxy) = (m[2] - mx * mx, m[3] - my * my, m[4] - mx * my);
                total += ((2.0 * mx * my + c1) * (2.0 * cxy + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
                count += 1;
            }
        }
    }
    Some(total / count as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn noise(w: usize, h: usize, seed: u64) -> RgbImage {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        RgbImage::from_fn(w, h, |_, _| [rng.random(), rng.random(), rng.random()])
    }

    #[test]
    fn psnr_of_a_known_error() {
        let a = RgbImage::from_fn(4, 4, |_, _| [0.5; 3]);
        let b = RgbImage::from_fn(4, 4, |_, _| [0.6; 3]);
        // MSE = 0.01 → 20 dB.
        assert!((psnr(&a, &b) - 20.0).abs() < 1e-4);
        assert_eq!(psnr(&a, &a), f64::INFINITY);
    }

    #[test]
    fn ssim_is_one_for_equal_images_and_drops_with_noise() {
        let a = noise(32, 24, 1);
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-12);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(2);
        let mut b = a.clone();
        for v in &mut b.data {
            *v = (*v + rng.random_range(-0.1..0.1f32)).clamp(0.0, 1.0);
        }
        let s_small = ssim(&a, &b).unwrap();
        let c = noise(32, 24, 3);
        let s_unrelated = ssim(&a, &c).unwrap();
        assert!(
            s_small < 0.999 && s_small > s_unrelated,
            "{s_small} vs {s_unrelated}"
        );
        assert!(
            s_unrelated.abs() < 0.1,
            "independent noise is uncorrelated: {s_unrelated}"
        );
        assert!(ssim(&noise(8, 8, 1), &noise(8, 8, 2)).is_none());
    }

    #[test]
    fn ssim_of_a_brightness_shift_matches_the_closed_form() {
        // A constant shift d leaves variances and covariance unchanged; only the luminance term
        // (2·mx·my + C1) / (mx² + my² + C1) moves. On a constant image it is exact.
        let a = RgbImage::from_fn(16, 16, |_, _| [0.4; 3]);
        let b = RgbImage::from_fn(16, 16, |_, _| [0.5; 3]);
        let c1 = 1e-4;
        let expect = (2.0 * 0.4 * 0.5 + c1) / (0.16 + 0.25 + c1);
        assert!((ssim(&a, &b).unwrap() - expect).abs() < 1e-6);
    }
}
