//! The `degrade` effect: image degradations `KIND:q` (../shared/DESIGN.md §6), applied to each
//! rendered view after exposure and clipping.

use super::SimError;
use crate::scene::RgbImage;
use rand::Rng;

/// A parsed degradation. The degradations themselves live in `neus_aug::augment`, which is not
/// part of this build yet: until it is, every `KIND:q` is refused with a clear error, so no
/// scene silently renders without the degradations it asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Degradation {}

impl Degradation {
    /// The degraded image.
    pub fn apply<R: Rng + ?Sized>(&self, _img: &RgbImage, _rng: &mut R) -> RgbImage {
        match *self {}
    }
}

/// Parses every `KIND:q` of `effects.degrade`, naming the one at fault.
pub fn parse_all(list: &[String]) -> Result<Vec<Degradation>, SimError> {
    match list.first() {
        None => Ok(Vec::new()),
        Some(first) => Err(SimError::Invalid {
            key: "effects.degrade".into(),
            problem: format!(
                "'{first}': degradations need the neus_aug::augment module, which this build \
                 does not include yet"
            ),
        }),
    }
}
