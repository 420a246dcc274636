//! Buffers of a training step and views of the flat parameter buffer: the per-shard
//! [`Scratch`] vectors (every chunk's intermediate values, forward and backward), the
//! [`WorkspaceCache`] that keeps them and the shards' gradient buffers between steps, and the
//! per-group slices ([`Groups`], [`GroupsMut`]) of a parameter or gradient buffer.
//!
//! Shapes below: `n` samples in the chunk, `d` = encoding width (`HashGrid::output_dim`, xyz
//! prefix + features), `f` = SDF network outputs (`sdf.feature_dim`; channel 0 is the SDF, the
//! rest the geometry feature), `dc` = colour network input width (`FieldConfig::color_input_dim`),
//! `wh`, `wc` = last hidden width of the SDF and colour networks. All rows are row-major.

use super::alpha::AlphaGrad;
use super::background::BackgroundScratch;
use crate::field::hashgrid::{stencil_rows, Sides};
use crate::field::mlp::MlpTape;
use crate::field::{ParamLayout, Real};

/// Buffers a training step keeps between calls so that it allocates and zeroes nothing of the
/// parameter size: the gradient buffers of shards `1..` (all zero between steps; shard 0 adds
/// into the caller's buffer) and each shard's scratch vectors.
pub(super) struct StepWorkspace<T> {
    pub(super) extra: Vec<Vec<T>>,
    pub(super) scratch: Vec<Scratch<T>>,
}

impl<T> Default for StepWorkspace<T> {
    fn default() -> Self {
        Self {
            extra: Vec::new(),
            scratch: Vec::new(),
        }
    }
}

/// A cache holding at most one [`StepWorkspace`] (of whichever scalar type was used last).
/// Taken out for the duration of a step and put back after it, so a step that panics drops it
/// (no half-written buffer is ever reused) and concurrent steps on one model each get their own.
/// Cloning a model gives the clone an empty cache. Holds about one gradient buffer per extra
/// shard (56 MB per shard for the default network).
#[derive(Default)]
pub(super) struct WorkspaceCache(std::sync::Mutex<Option<Box<dyn std::any::Any + Send>>>);

impl WorkspaceCache {
    pub(super) fn take<T: Real>(&self) -> StepWorkspace<T> {
        let cached = self.0.lock().ok().and_then(|mut g| g.take());
        cached
            .and_then(|b| b.downcast::<StepWorkspace<T>>().ok())
            .map(|b| *b)
            .unwrap_or_default()
    }

    pub(super) fn put<T: Real>(&self, ws: StepWorkspace<T>) {
        if let Ok(mut g) = self.0.lock() {
            *g = Some(Box::new(ws));
        }
    }
}

impl Clone for WorkspaceCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for WorkspaceCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WorkspaceCache")
    }
}

/// Mutable gradient views of each group.
pub(super) struct GroupsMut<'a, T> {
    pub(super) hash: &'a mut [T],
    pub(super) sdf: &'a mut [T],
    pub(super) color: &'a mut [T],
    pub(super) var: &'a mut [T],
    pub(super) app: &'a mut [T],
    /// The background networks (empty without a learned background).
    pub(super) bg_density: &'a mut [T],
    pub(super) bg_color: &'a mut [T],
}

/// Read-only parameter views of each group.
pub(super) struct Groups<'a, T> {
    pub(super) hash: &'a [T],
    pub(super) sdf: &'a [T],
    pub(super) color: &'a [T],
    pub(super) var: &'a [T],
    pub(super) app: &'a [T],
    /// The background networks (empty without a learned background).
    pub(super) bg_density: &'a [T],
    pub(super) bg_color: &'a [T],
}

/// Per-shard buffers, reused across chunks (resized, never shrunk; a phase overwrites what it
/// reads later). Sample `i` of a chunk is its `i`-th sample in ray order.
#[derive(Default)]
pub(super) struct Scratch<T> {
    /// `[n][3]` sample positions (interval midpoints), normalised space.
    pub(super) points: Vec<[T; 3]>,
    /// `[n][axis][+/−]` finite-difference tap coordinates `x_a ± ε`, clamped to the box (the −
    /// tap is `x_a` itself on samples with forward differences).
    pub(super) tap_points: Vec<[[T; 2]; 3]>,
    /// `[n + 1]` tap layout: sample `i`'s taps are tap rows `tap_off[i]..tap_off[i + 1]` (six,
    /// `[+x, −x, +y, −y, +z, −z]`, for central differences; three, `[±x, ±y, ±z]`, for one-sided
    /// ones; `RenderConfig::fd_central_every`); `m = tap_off[n]` tap rows in all.
    pub(super) tap_off: Vec<usize>,
    /// `[n]` the taps each sample uses: both sides (central) or one (see `tap_off`).
    pub(super) tap_sides: Vec<Sides>,
    /// `[n][3]` unit direction of each sample's ray.
    pub(super) dirs: Vec<[T; 3]>,
    /// `[n]` distance of each sample along its ray (normalised units), the `t` of compositing.
    pub(super) ray_t: Vec<T>,
    /// `[n + m + 1][d]` hash encodings: centres in rows `0..n`, sample `i`'s taps in rows
    /// `n + tap_off[i] + k`, one spare row last ([`tap_rows`]).
    pub(super) encoding: Vec<T>,
    /// SDF network activations on the `n + m` centre and tap rows (input of its backward).
    pub(super) sdf_tape: MlpTape<T>,
    /// `[n][f]` SDF network outputs at the centres: SDF (channel 0) and geometry feature.
    pub(super) sdf_feature: Vec<T>,
    /// `[m]` SDF at the taps, in tap-row order (channel 0 only, from the hidden layer's epilogue).
    pub(super) tap_sdf: Vec<T>,
    /// `[n][3]` finite-difference SDF gradient `∇f` (central or forward, see `tap_off`).
    pub(super) sdf_grad: Vec<[T; 3]>,
    /// `[n][3]` normal `∇f / max(|∇f|, 1e-12)`.
    pub(super) normal: Vec<[T; 3]>,
    /// `[n][dc]` colour network input: feature, SH of the direction, normal, appearance code (and
    /// scalar `p`).
    pub(super) color_in: Vec<T>,
    /// Colour network activations (input of its backward).
    pub(super) color_tape: MlpTape<T>,
    /// `[n][3]` colour network outputs before the sigmoid.
    pub(super) color_logits: Vec<T>,
    /// `[n][3]` sample colours, `sigmoid(color_logits)`.
    pub(super) rgb: Vec<[T; 3]>,
    /// `[n]` NeuS alpha of each sample.
    pub(super) alpha: Vec<T>,
    /// `[n]` partial derivatives of each alpha (SDF, cos, inv_s); zero when not training.
    pub(super) alpha_grad: Vec<AlphaGrad<T>>,
    /// `[n]` `∂L/∂alpha` from the compositing backward.
    pub(super) d_alpha: Vec<T>,
    /// `[n][3]` `∂L/∂rgb` of each sample colour.
    pub(super) d_rgb: Vec<[T; 3]>,
    /// `[n][3]` `∂L/∂color_logits`.
    pub(super) d_color_logits: Vec<T>,
    /// `[n][wc]` `∂L/∂` the colour network's last hidden layer (then its earlier layers, in place).
    pub(super) d_color_hidden: Vec<T>,
    /// `[n][dc]` `∂L/∂color_in`.
    pub(super) d_color_in: Vec<T>,
    /// `[n][f]` `∂L/∂sdf_feature`.
    pub(super) d_sdf_feature: Vec<T>,
    /// `[m]` `∂L/∂tap_sdf`.
    pub(super) d_tap_sdf: Vec<T>,
    /// `[n + m][wh]` `∂L/∂` the SDF network's last hidden layer on all rows (then earlier layers).
    pub(super) d_sdf_hidden: Vec<T>,
    /// `[n + m + 1][d]` `∂L/∂encoding`; only the hash-grid columns are written, the spare row
    /// is zero.
    pub(super) d_encoding: Vec<T>,
    /// Work buffer of the MLP backward passes (no meaning between calls).
    pub(super) mlp_work: Vec<T>,
    /// The learned background's buffers (unused without one; shapes in [`BackgroundScratch`]).
    pub(super) bg: BackgroundScratch<T>,
    /// `[nb][3]` background sample positions (normalised space, f64: the encoding is computed
    /// in f64 and carries no gradient), `nb` = rays of the chunk × `n_outside`, ray after ray.
    pub(super) bg_x: Vec<[f64; 3]>,
    /// `[nb][3]` unit direction of each background sample's ray.
    pub(super) bg_dirs: Vec<[T; 3]>,
    /// `[nb]` background sample distances and `[nb]` interval lengths (normalised units).
    pub(super) bg_t: Vec<T>,
    pub(super) bg_dt: Vec<T>,
}

/// Rows of sample `i`'s centre (row `i`) and its seven stencil points in the `[n + m + 1][d]`
/// buffers, in [`crate::field::HashGrid::encode_fd`]'s order (centre, then `[axis][+/−]`), for
/// the tap layout `off` (`Scratch::tap_off`, `n + 1` entries) and `sides` (`Scratch::tap_sides`),
/// and the sides in use (see [`crate::field::HashGrid::encode_fd_batch`]).
#[inline]
pub(super) fn tap_rows(
    i: usize,
    n: usize,
    d: usize,
    off: &[usize],
    sides: &[Sides],
) -> ([usize; 7], Sides) {
    let o = n + off[i];
    let side = sides[i];
    let rows = match side {
        Sides::Both => stencil_rows(i, o, d),
        // One-sided: the unused side's taps sit on the centre and are skipped by the
        // level-parallel stencil; the per-sample fallback writes them into the spare row after
        // the last tap row, which nothing reads (its gradient row is zero).
        Sides::Plus | Sides::Minus => {
            let spare = (n + off[n]) * d;
            let mut r = [spare; 7];
            r[0] = i * d;
            let s = side.slots().start;
            for a in 0..3 {
                r[1 + 2 * a + s] = (o + a) * d;
            }
            r
        }
    };
    (rows, side)
}

/// Names of the parameter groups, in the order [`super::NeusModel::new`] lays them out.
pub(super) const HASH_GRID: &str = "hash_grid";
pub(super) const SDF_MLP: &str = "sdf_mlp";
pub(super) const COLOR_MLP: &str = "color_mlp";
pub(super) const VARIANCE: &str = "variance";
pub(super) const APPEARANCE: &str = "appearance";
/// The learned background's groups, after the five above and only when it is on.
pub(super) const BG_DENSITY: &str = "bg_density";
pub(super) const BG_COLOR: &str = "bg_color";

/// The index range of an optional group (empty, at the end, when the layout lacks it).
fn optional_group(layout: &ParamLayout, name: &str) -> std::ops::Range<usize> {
    layout
        .group(name)
        .map_or(layout.total()..layout.total(), |g| g.range())
}

/// The flat index range of the group `name` (every model layout has all five groups).
pub(super) fn group(layout: &ParamLayout, name: &str) -> std::ops::Range<usize> {
    layout
        .group(name)
        .unwrap_or_else(|| panic!("parameter group '{name}' missing from the layout"))
        .range()
}

/// Read-only views of the groups of a parameter buffer.
pub(super) fn split<'a, T>(layout: &ParamLayout, p: &'a [T]) -> Groups<'a, T> {
    Groups {
        hash: &p[group(layout, HASH_GRID)],
        sdf: &p[group(layout, SDF_MLP)],
        color: &p[group(layout, COLOR_MLP)],
        var: &p[group(layout, VARIANCE)],
        app: &p[group(layout, APPEARANCE)],
        bg_density: &p[optional_group(layout, BG_DENSITY)],
        bg_color: &p[optional_group(layout, BG_COLOR)],
    }
}

/// Mutable views of the groups of a parameter (or gradient) buffer.
pub(super) fn split_mut<'a, T>(layout: &ParamLayout, p: &'a mut [T]) -> GroupsMut<'a, T> {
    // The groups are contiguous in layout order: cut the buffer at each group's end.
    let len = |name| group(layout, name).len();
    debug_assert_eq!(group(layout, SDF_MLP).start, len(HASH_GRID));
    let (hash, rest) = p.split_at_mut(len(HASH_GRID));
    let (sdf, rest) = rest.split_at_mut(len(SDF_MLP));
    let (color, rest) = rest.split_at_mut(len(COLOR_MLP));
    let (var, rest) = rest.split_at_mut(len(VARIANCE));
    let (app, rest) = rest.split_at_mut(len(APPEARANCE));
    let (bg_density, rest) = rest.split_at_mut(optional_group(layout, BG_DENSITY).len());
    let (bg_color, _) = rest.split_at_mut(optional_group(layout, BG_COLOR).len());
    GroupsMut {
        hash,
        sdf,
        color,
        var,
        app,
        bg_density,
        bg_color,
    }
}
