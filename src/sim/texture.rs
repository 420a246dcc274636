//! Procedural solid textures: albedo as a function of the surface point in the rig frame (mm),
//! so any mesh is textured without UV coordinates, and seeded so a scene's seed fixes them.
//!
//! The noise is lattice value noise: a hashed value in `[0, 1)` at every integer lattice point,
//! interpolated trilinearly with the quintic fade `6t⁵ − 15t⁴ + 10t³` (Perlin, "Improving Noise",
//! SIGGRAPH 2002) so it is C² smooth. The hash is the splitmix64 finaliser (Steele, Lea & Flood,
//! "Fast splittable pseudorandom number generators", OOPSLA 2014) of the packed lattice
//! coordinates and the seed.

use super::desc::Pattern;

/// A procedural albedo: pattern, middle scale (mm) and seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolidTexture {
    /// The pattern.
    pub pattern: Pattern,
    /// Middle scale (mm).
    pub scale_mm: f32,
    /// Seed of the noise lattice.
    pub seed: u64,
}

/// splitmix64's output function: a bijective 64-bit mix.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A value in `[0, 1)` for lattice point `(x, y, z)` and `seed`.
fn lattice(x: i32, y: i32, z: i32, seed: u64) -> f32 {
    // The seed is mixed first: a raw `seed ^ x` would merely permute lattice values between
    // seeds that differ in low bits.
    let h = mix64(mix64(mix64(mix64(seed) ^ x as u32 as u64) ^ y as u32 as u64) ^ z as u32 as u64);
    (h >> 40) as f32 / (1u64 << 24) as f32
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Value noise in `[0, 1)` at `p` (lattice units).
pub fn value_noise(p: [f32; 3], seed: u64) -> f32 {
    let f = p.map(f32::floor);
    let i = f.map(|v| v as i32);
    let t = [fade(p[0] - f[0]), fade(p[1] - f[1]), fade(p[2] - f[2])];
    let c = |dx: i32, dy: i32, dz: i32| lattice(i[0] + dx, i[1] + dy, i[2] + dz, seed);
    let x00 = lerp(c(0, 0, 0), c(1, 0, 0), t[0]);
    let x10 = lerp(c(0, 1, 0), c(1, 1, 0), t[0]);
    let x01 = lerp(c(0, 0, 1), c(1, 0, 1), t[0]);
    let x11 = lerp(c(0, 1, 1), c(1, 1, 1), t[0]);
    lerp(lerp(x00, x10, t[1]), lerp(x01, x11, t[1]), t[2])
}

fn smoothstep(e0: f32, e1: f32, v: f32) -> f32 {
    let t = ((v - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// `p / s`, turned by a fixed rotation that differs per `layer`, so no layer's lattice lines up
/// with the axes or with another layer's (axis-aligned value noise shows blocky artefacts).
fn scaled(p: [f32; 3], s: f32, layer: u32) -> [f32; 3] {
    // Rotation about z by a, then about x by b (radians, fixed per layer).
    let (a, b) = (0.61 + 1.13 * layer as f32, 0.37 + 0.79 * layer as f32);
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    let q = [ca * p[0] - sa * p[1], sa * p[0] + ca * p[1], p[2]];
    [
        q[0] / s,
        (cb * q[1] - sb * q[2]) / s,
        (sb * q[1] + cb * q[2]) / s,
    ]
}

impl SolidTexture {
    /// The albedo in `[0.02, 0.98]³` at rig-frame point `p` (mm).
    pub fn albedo(&self, p: [f32; 3]) -> [f32; 3] {
        let s = self.scale_mm;
        match self.pattern {
            Pattern::Multiscale => {
                // Large colour regions (hue), mid-scale dark/light spots, fine grain.
                let big = value_noise(scaled(p, 3.5 * s, 0), self.seed ^ 0x1);
                let mid = value_noise(scaled(p, s, 1), self.seed ^ 0x2);
                let fine = value_noise(scaled(p, 0.25 * s, 2), self.seed ^ 0x3);
                let t = 1.7 * big + 0.1 * mid;
                let tau = std::f32::consts::TAU;
                let hue = [0.0f32, 0.33, 0.67].map(|d| 0.5 + 0.45 * (tau * (t + d)).cos());
                let spots = 0.25 + 0.75 * smoothstep(0.42, 0.58, mid);
                let grain = 0.8 + 0.4 * fine;
                hue.map(|h| (h * spots * grain).clamp(0.02, 0.98))
            }
            Pattern::Checker => {
                let k = p.map(|c| (c / s).floor() as i64).iter().sum::<i64>();
                if k.rem_euclid(2) == 0 {
                    [0.85, 0.8, 0.7]
                } else {
                    [0.15, 0.2, 0.3]
                }
            }
            Pattern::Noise => {
                let mut v = 0.0;
                let mut amp = 0.5;
                let mut freq = 1.0;
                for octave in 0..4u64 {
                    v += amp
                        * value_noise(
                            scaled(p, s / freq, octave as u32),
                            self.seed ^ (0x10 + octave),
                        );
                    amp *= 0.5;
                    freq *= 2.0;
                }
                let g = (0.1 + 0.8 * v / 0.9375).clamp(0.02, 0.98);
                [g, g, g]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_in_range_continuous_and_seeded() {
        let mut prev = value_noise([0.0, 0.3, 0.7], 5);
        let mut lo: f32 = 1.0;
        let mut hi: f32 = 0.0;
        for i in 1..20000 {
            let x = i as f32 * 1e-3;
            let v = value_noise([x, 0.3, 0.7], 5);
            assert!((0.0..1.0).contains(&v));
            // Lipschitz: the quintic fade's slope is at most 15/8 per lattice unit.
            assert!((v - prev).abs() <= 1.9e-3 + 1e-6, "jump at {x}");
            prev = v;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        assert!(hi - lo > 0.5, "noise barely varies: {lo}..{hi}");
        assert_ne!(
            value_noise([1.5, 2.5, 3.5], 1),
            value_noise([1.5, 2.5, 3.5], 2)
        );
        assert_eq!(
            value_noise([1.5, 2.5, 3.5], 1),
            value_noise([1.5, 2.5, 3.5], 1)
        );
    }

    #[test]
    fn multiscale_texture_has_high_contrast_at_several_scales() {
        let tex = SolidTexture {
            pattern: Pattern::Multiscale,
            scale_mm: 16.0,
            seed: 0,
        };
        let lum = |p: [f32; 3]| {
            let a = tex.albedo(p);
            0.3 * a[0] + 0.59 * a[1] + 0.11 * a[2]
        };
        // Luminance spread along a 200 mm line, sampled every 0.5 mm.
        let vals: Vec<f32> = (0..400)
            .map(|i| lum([i as f32 * 0.5 - 100.0, 3.0, 7.0]))
            .collect();
        let (lo, hi) = vals
            .iter()
            .fold((1f32, 0f32), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(hi - lo > 0.4, "contrast {lo}..{hi}");
        // Fine scale: neighbouring 2 mm samples differ noticeably somewhere.
        let fine = vals
            .windows(5)
            .map(|w| (w[4] - w[0]).abs())
            .fold(0f32, f32::max);
        assert!(fine > 0.05, "no fine-scale variation ({fine})");
        for p in [[0.0, 0.0, 0.0], [55.5, -3.2, 17.0]] {
            assert!(tex.albedo(p).iter().all(|c| (0.02..=0.98).contains(c)));
        }
    }
}
