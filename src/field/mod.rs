//! The NeuS field: a multiresolution hash grid ([`hashgrid`]) feeding an SDF MLP ([`mlp`]) whose
//! 13 outputs (SDF + 12 features) feed, together with spherical harmonics of the view direction
//! ([`sh`]), the normal and an appearance code, a colour MLP.
//!
//! A field maps positions to values and knows nothing of rays (rays, sampling and compositing live
//! in [`crate::render`]). All parameters live in one flat buffer described by [`ParamLayout`]
//! ([`params`]), so AdamW and checkpoints see one layout.
//!
//! The math is generic over [`Real`] (`f32` in the hot paths, `f64` for the finite-difference
//! checks), so the gradient tests exercise exactly the code that trains.
//!
//! Reference facts: instant-nsr-pl `models/geometry.py`,
//! `models/network_utils.py`, `models/texture.py`, `configs/neus-dtu-wmask.yaml`.

pub mod alloc;
pub mod config;
pub mod dense;
pub mod fastmath;
pub mod hashgrid;
pub mod lanes;
pub mod mlp;
pub mod params;
pub mod sh;

pub use config::{ColorMlpConfig, FieldConfig, HashGridConfig, SdfMlpConfig};
pub use hashgrid::HashGrid;
pub use mlp::{Activation, Mlp};
pub use params::{ParamGroup, ParamLayout};

use std::fmt::Debug;

/// Whether this build fuses multiply-add in hardware: x86 with the `fma` target feature
/// (x86-64-v3 and up) and every aarch64 core (`fmadd`; Rust names no `fma` feature there). It
/// chooses [`Real::fma`]'s form and the range reduction of [`fastmath::exp_nonpos_f32`]; being a
/// constant, the branch not taken is compiled out.
pub const HAS_FMA: bool = cfg!(any(target_feature = "fma", target_arch = "aarch64"));
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Floating-point scalar the network math is generic over: `f32` (training, inference) or `f64`
/// (finite-difference gradient checks).
pub trait Real:
    Copy
    + Send
    + Sync
    + Debug
    + Default
    + PartialOrd
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    const ZERO: Self;
    const ONE: Self;
    fn from_f64(x: f64) -> Self;
    fn from_f32(x: f32) -> Self;
    fn to_f64(self) -> f64;
    fn to_f32(self) -> f32;
    fn exp(self) -> Self;
    fn ln(self) -> Self;
    fn ln_1p(self) -> Self;
    fn exp_m1(self) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn floor(self) -> Self;
    fn maxv(self, o: Self) -> Self;
    fn minv(self, o: Self) -> Self;
    fn is_finite(self) -> bool;
    /// The grid cell of a floored position: `self` clamped to the `i32` range (NaN → `i32::MIN`),
    /// converted to `i32` and reinterpreted as `u32`, wrapping below 0 like tcnn's
    /// `(uint32_t)(int)floor(pos)`. Written so that it vectorises (a saturating `as` cast does
    /// not).
    fn cell_u32(self) -> u32;
    /// `self·a + b`, fused (one rounding) where the target has FMA instructions, else two
    /// operations (Rust never contracts `a*b + c` by itself, and a software `fma` call would be
    /// far slower than the two roundings).
    fn fma(self, a: Self, b: Self) -> Self;
    /// Softplus `ln(1 + e^{βz})/β` and its derivative `σ(βz)`, computed as
    /// `max(z,0) + ln1p(e^{−|βz|})/β` (no overflow, no threshold). `f64` uses the standard library;
    /// `f32` uses branch-free polynomial `exp`/`ln1p` that vectorise ([`fastmath::softplus_f32`]),
    /// within [`fastmath::SOFTPLUS_MAX_REL_ERROR`]` · (1 + β|z|)` relative (tested).
    fn softplus_and_grad(z: Self, beta: Self) -> (Self, Self);
    /// `C = alpha·A·B + beta·C` for row/column-strided matrices: `A` is `m×k`, `B` is `k×n`, `C`
    /// is `m×n` (strides in elements). Dispatches to `matrixmultiply::{sgemm,dgemm}`.
    ///
    /// # Safety
    /// The strides and sizes must describe valid, non-overlapping (for `C`) regions of the slices;
    /// callers in this crate check the slice lengths before calling.
    #[allow(clippy::too_many_arguments)]
    unsafe fn gemm(
        m: usize,
        k: usize,
        n: usize,
        alpha: Self,
        a: *const Self,
        rsa: isize,
        csa: isize,
        b: *const Self,
        rsb: isize,
        csb: isize,
        beta: Self,
        c: *mut Self,
        rsc: isize,
        csc: isize,
    );
}

macro_rules! impl_real {
    ($t:ty, $gemm:path, $softplus:path) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn from_f32(x: f32) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn to_f32(self) -> f32 {
                self as f32
            }
            #[inline(always)]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline(always)]
            fn ln(self) -> Self {
                <$t>::ln(self)
            }
            #[inline(always)]
            fn ln_1p(self) -> Self {
                <$t>::ln_1p(self)
            }
            #[inline(always)]
            fn exp_m1(self) -> Self {
                <$t>::exp_m1(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn floor(self) -> Self {
                <$t>::floor(self)
            }
            #[inline(always)]
            fn maxv(self, o: Self) -> Self {
                if self > o {
                    self
                } else {
                    o
                }
            }
            #[inline(always)]
            fn minv(self, o: Self) -> Self {
                if self < o {
                    self
                } else {
                    o
                }
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn fma(self, a: Self, b: Self) -> Self {
                if HAS_FMA {
                    self.mul_add(a, b)
                } else {
                    self * a + b
                }
            }
            #[inline(always)]
            fn cell_u32(self) -> u32 {
                let v = self.max(-2_147_483_648.0).min(2_147_483_520.0);
                // SAFETY: `v` is finite (max of NaN and a number is the number) and inside the
                // i32 range.
                unsafe { v.to_int_unchecked::<i32>() as u32 }
            }
            #[inline(always)]
            fn softplus_and_grad(z: Self, beta: Self) -> (Self, Self) {
                $softplus(z, beta)
            }
            #[inline]
            unsafe fn gemm(
                m: usize,
                k: usize,
                n: usize,
                alpha: Self,
                a: *const Self,
                rsa: isize,
                csa: isize,
                b: *const Self,
                rsb: isize,
                csb: isize,
                beta: Self,
                c: *mut Self,
                rsc: isize,
                csc: isize,
            ) {
                if m == 0 || n == 0 {
                    return;
                }
                // SAFETY: forwarded contract of `Real::gemm`.
                unsafe { $gemm(m, k, n, alpha, a, rsa, csa, b, rsb, csb, beta, c, rsc, csc) }
            }
        }
    };
}
impl_real!(f32, matrixmultiply::sgemm, fastmath::softplus_f32);
impl_real!(f64, matrixmultiply::dgemm, fastmath::softplus_f64);

/// Numerically stable logistic sigmoid `1/(1+e^{-x})`: never overflows, saturates to exactly 0 or
/// 1 for large `|x|`.
#[inline(always)]
pub fn sigmoid<T: Real>(x: T) -> T {
    if x >= T::ZERO {
        T::ONE / (T::ONE + (-x).exp())
    } else {
        let e = x.exp();
        e / (T::ONE + e)
    }
}
