//! The pieces of the hash grid's geometry that both of its encoders share, the per-point path
//! ([`super::HashGrid`]) and the level-parallel one (`field::lanes`): a level, the hashing primes
//! and which finite-difference taps a sample uses.

/// One resolution level of the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// `base·b^l − 1`.
    pub scale: f64,
    /// `ceil(scale) + 1` (dense index stride).
    pub resolution: u32,
    /// First entry of this level in the table.
    pub offset: usize,
    /// Entries of this level.
    pub size: u32,
    /// Hashed (true) or dense (false).
    pub hashed: bool,
}

/// Spatial-hash primes per axis (tcnn `grid.h`; Müller et al. 2022 eq. 4): a hashed corner's
/// entry is `(x·P0 ^ y·P1 ^ z·P2) mod T`, wrapping `u32`. Shared with the level-parallel
/// path (`field::lanes`).
pub const PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

/// Which taps of a finite-difference stencil a sample uses in the batched paths
/// (`HashGrid::encode_fd_batch`): both (a central difference) or the `+ε` or the `−ε` ones
/// alone (a one-sided difference). The taps of an unused side must sit on the centre.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sides {
    Both,
    Plus,
    Minus,
}

impl Sides {
    /// The tap slots in use (`0` = `+ε`, `1` = `−ε`).
    #[inline(always)]
    pub fn slots(self) -> std::ops::Range<usize> {
        match self {
            Sides::Both => 0..2,
            Sides::Plus => 0..1,
            Sides::Minus => 1..2,
        }
    }
}
