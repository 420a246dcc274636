//! Colour-only image augmentations (the paper's SIA and DIA), image degradations and reduced data.
//!
//! Reference: Pérez et al., "Enhancing Neural Rendering Methods with Image Augmentations", §3
//! (SIA, DIA, appearance embeddings) and the appendix (degradations).
//!
//! # Which type to pick
//! - [`Manipulation`]: the five colour manipulations plus the identity, each `M(I, p)` on `[0, 1]`
//!   RGB with `M(I, 0) = I` bit for bit. [`Manipulation::apply`] transforms a whole image (the
//!   reference); [`PixelSource::pixel`] computes one output pixel from the original image (the
//!   fast path DIA uses, tested to be bit-identical to the reference).
//! - [`Degradation`]: Gaussian, motion blur, Poisson, salt & pepper and speckle, each with one
//!   strength `q`; parsed from `KIND:q` ([`std::str::FromStr`]), applied with an explicit RNG.
//! - [`AugmentConfig`] + [`AugSampler`]: what the training loop uses. Given a chosen training pixel
//!   `(view, x, y)`, the sampler returns `(rgb, code, p)` for `none`, `sia` or `dia`.
//! - [`views_fraction`]: the seeded subset of training views for the reduced-data experiments.
//! - [`ImageOp`]: "any manipulation or degradation", as the `augment --apply KIND:v` CLI takes it.
//! - [`contact_sheet`]: one view under every manipulation and degradation, to look at before
//!   training.
//!
//! # Semantics (torchvision `adjust_*` / Pillow `ImageEnhance`, factor `f = 1 + p`)
//! All results are clipped to `[0, 1]`. Blends are written `x·f + d·(1 − f)`, which is exactly `x`
//! when `f = 1`, so every manipulation is bit-exactly the identity at `p = 0`.
//! - brightness: `x·f` (Pillow blends with a black image).
//! - contrast: blend with the image's mean grayscale (one number per image; luma ITU-R 601-2
//!   `0.299 R + 0.587 G + 0.114 B`, Pillow's `convert("L")`). We use the exact float mean, as
//!   torchvision does for float tensors; Pillow rounds the mean of its 8-bit luma image to an
//!   integer level (`scripts/crosscheck_augment.py` explains how the comparison accounts for it).
//! - saturation: blend with the pixel's own grayscale (Pillow `ImageEnhance.Color`).
//! - hue: rotate the HSV hue by `p` turns, `p ∈ [-0.5, 0.5]` (torchvision `adjust_hue`); value and
//!   saturation are unchanged, so gray pixels stay exactly gray and nothing clips.
//! - sharpness: blend with the 3×3 smoothed image, kernel `[[1,1,1],[1,5,1],[1,1,1]] / 13`
//!   (Pillow's `ImageFilter.SMOOTH`); the one-pixel border is left unchanged, as Pillow's
//!   `ImagingFilter3x3` copies it and torchvision's `_blurred_degenerate_image` keeps it.
//!
//! `p` ranges (checked where user input enters: parsing and [`AugmentConfig::validate`]):
//! `[-1, 1]` (factor `[0, 2]`) for brightness, contrast, saturation and sharpness; `[-0.5, 0.5]`
//! for hue; the identity takes only `p = 0`.
//!
//! # SIA and DIA
//! - SIA (static): `N + 1 = 6` replicas of the training set, the original plus one per
//!   manipulation at its fixed intensity `p_i` ([`SiaIntensities`]), computed once (memory 6×).
//!   Each training ray picks a replica uniformly; the colour network receives `Emb(M)` (the
//!   embedding row of the replica's [`Manipulation::code`]) and `p = 0`.
//! - DIA (dynamic): each ray (or each image, when a batch comes from one image) draws `M`
//!   uniformly from the five non-identity manipulations and `p ~ U[-w_M/2, w_M/2)` ([`DiaWidths`]);
//!   the colour network receives `[Emb(M), p]`. Only the sampled pixels are manipulated
//!   ([`PixelSource`]: contrast's mean is precomputed per image, sharpness reads the 3×3
//!   neighbourhood), so DIA costs a few arithmetic operations per ray instead of re-rendering
//!   whole images (the paper measured 3× the baseline's training time).
//! - Test time: the model is queried with the identity, code 0, and `p = 0`
//!   ([`AugSample::TEST`]).
//!
//! # The identity embedding under DIA (make it explicit)
//! The paper's DIA never draws the identity, so the identity's embedding row (code 0) receives no
//! gradient. The appearance table is zero-initialised (the model's choice, made in `field`), and
//! a row that never receives a gradient stays at zero (AdamW's decoupled weight decay keeps zero at
//! zero). So under the paper's DIA the test-time embedding is `[0…0, p = 0]`: the common starting
//! point of every code and the centre of every manipulation's `p` range, a point the network was
//! never trained on but which lies between the codes it was. Setting
//! [`AugmentConfig::include_identity`] `= true` draws the identity (with `p = 0`) as a sixth
//! choice, which trains the row the model is tested with. SIA always trains it (the original
//! images are one of its replicas).
//!
//! # Default intensities and widths (the paper publishes neither)
//! SIA `p_i` ([`SiaIntensities::default`]): brightness −0.3, contrast −0.3, saturation −0.4,
//! hue +0.1 turn (36°), sharpness +1.0. Rule: each replica must be plainly visible (a change of
//! about a third of the range, or a third of the way round the colour wheel) yet lose no
//! information, so one surface explains every replica. Darkening, flattening contrast towards the
//! mean, desaturating and rotating hue never clip; the alternatives (brightening, more contrast or
//! saturation) would clip highlights, which DTU's white-lit objects have plenty of. Sharpness is
//! the exception: factor 2 (the value torchvision's `RandomAdjustSharpness` is usually given)
//! clips only at strong edges, whereas the opposite choice (factor 0, fully smoothed) would
//! discard the fine texture the photometric loss relies on.
//!
//! DIA widths `w_i` ([`DiaWidths::default`]): 0.8 for brightness, contrast and saturation, 0.2 for
//! hue, 2.0 for sharpness, i.e. factors in `[0.6, 1.4]`, hue within ±0.1 turn and sharpness
//! factors in `[0, 2]`. These are torchvision's widely used `ColorJitter(0.4, 0.4, 0.4, 0.1)`
//! (factor `1 ± 0.4`, hue ±0.1) and `RandomAdjustSharpness(2)` ranges, moderate changes that
//! stay recognisable. Every SIA intensity lies inside DIA's range or on its edge, so the two modes
//! train on changes of comparable size and differ only in static versus dynamic sampling.
//!
//! # Degradations and reduced data
//! [`Degradation`] implements the paper's appendix effects on `[0, 1]` values, then clips. Each is
//! seeded through the caller's RNG; [`degrade_views`] derives one stream per view from a seed so
//! the result does not depend on the order in which views are processed. [`views_fraction`]
//! keeps a seeded random subset of views (nested: the 10 % subset lies inside the 25 % one).

mod config;
mod degradation;
mod manipulation;
mod sampler;
mod sheet;
mod spec;
mod views;

pub use crate::scene::image::{luma, LUMA_WEIGHTS};
pub use config::{AugMode, AugmentConfig, DiaWidths, SiaIntensities};
pub use degradation::{degrade_views, motion_blur_kernel, Degradation, DegradationKind};
pub use manipulation::{gray_mean, Manipulation, PixelSource};
pub use sampler::{AugChoice, AugSample, AugSampler, PixelRef};
pub use sheet::{contact_sheet, downscale_to_fit, ContactSheet};
pub use spec::ImageOp;
pub use views::views_fraction;

/// Errors of the augmentation module: every variant names the value at fault and what was
/// expected, so a bad command line or config file can be fixed from the message alone.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AugmentError {
    /// A manipulation, degradation or mode name that does not exist.
    #[error("unknown {what} `{name}`; expected one of: {expected}")]
    UnknownName {
        /// "manipulation", "degradation", "manipulation or degradation", "augmentation mode".
        what: &'static str,
        /// The name as given.
        name: String,
        /// The valid names, comma separated.
        expected: String,
    },
    /// A strength `p` or `q`, a width or a fraction outside its valid range (or not finite).
    #[error("{what} = {value} is out of range: expected {range}")]
    OutOfRange {
        /// What the value is, e.g. `hue p`, `gaussian q`, `augment.dia_width.hue`.
        what: String,
        /// The offending value, as written (shortest round-trip form).
        value: String,
        /// The valid range in interval notation, e.g. `[-0.5, 0.5]`.
        range: String,
    },
    /// A `KIND:value` spec that cannot be parsed.
    #[error("cannot parse `{spec}`: {reason}")]
    BadSpec {
        /// The spec as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A views fraction that leaves no training view, or a set with no views at all.
    #[error("cannot keep a fraction {fraction} of {n_views} views: {reason}")]
    ViewsFraction {
        /// The requested fraction.
        fraction: f64,
        /// The number of views available.
        n_views: usize,
        /// Why it is impossible.
        reason: String,
    },
    /// An augmentation sampler built on no images, or on an empty image.
    #[error("augmentation needs at least one non-empty training image: {reason}")]
    NoImages {
        /// What was found instead.
        reason: String,
    },
}

/// Formats a range for error messages: `[lo, hi]`, `(lo, hi]`, ...
pub(crate) fn range_text(lo: f64, lo_inclusive: bool, hi: f64, hi_inclusive: bool) -> String {
    format!(
        "{}{lo}, {hi}{}",
        if lo_inclusive { '[' } else { '(' },
        if hi_inclusive { ']' } else { ')' }
    )
}

/// Normalises a user-given name: ASCII lower case, `_` and spaces read as `-`.
pub(crate) fn normalise_name(name: &str) -> String {
    name.trim().to_ascii_lowercase().replace(['_', ' '], "-")
}
