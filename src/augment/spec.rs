//! `KIND:value` specs naming any manipulation or degradation (the `augment --apply` CLI).

use super::degradation::parse_number;
use super::{AugmentError, Degradation, DegradationKind, Manipulation};
use crate::scene::image::RgbImage;
use rand::Rng;
use std::fmt;
use std::str::FromStr;

/// One image operation: a manipulation with its `p` or a degradation with its `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ImageOp {
    /// `M(I, p)`, `p` checked against [`Manipulation::p_range`].
    Manipulate(Manipulation, f32),
    /// A degradation (its `q` already checked).
    Degrade(Degradation),
}

impl ImageOp {
    /// Applies the operation; `rng` is used by the random degradations only.
    pub fn apply<R: Rng + ?Sized>(&self, img: &RgbImage, rng: &mut R) -> RgbImage {
        match self {
            ImageOp::Manipulate(m, p) => m.apply(img, *p),
            ImageOp::Degrade(d) => d.apply(img, rng),
        }
    }
}

impl fmt::Display for ImageOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImageOp::Manipulate(m, p) => write!(f, "{m}:{p}"),
            ImageOp::Degrade(d) => write!(f, "{d}"),
        }
    }
}

impl FromStr for ImageOp {
    type Err = AugmentError;

    /// `NAME:value`, NAME a manipulation (value = `p`, required) or a degradation (value = `q`,
    /// optional: the paper default). Unknown names list every valid one.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (name, value) = match s.split_once(':') {
            Some((n, v)) => (n, Some(v)),
            None => (s, None),
        };
        if let Ok(m) = name.parse::<Manipulation>() {
            let p = match value {
                Some(v) => parse_number(s, v)?,
                None if m == Manipulation::Identity => 0.0,
                None => {
                    return Err(AugmentError::BadSpec {
                        spec: s.to_string(),
                        reason: format!(
                            "a manipulation needs its intensity, e.g. `{}:{}`",
                            m.name(),
                            m.p_range().1 / 4.0
                        ),
                    })
                }
            };
            m.check_p(p)?;
            return Ok(ImageOp::Manipulate(m, p));
        }
        if name.parse::<DegradationKind>().is_ok() {
            return Ok(ImageOp::Degrade(s.parse()?));
        }
        let names: Vec<&str> = Manipulation::ALL
            .iter()
            .map(|m| m.name())
            .chain(DegradationKind::ALL.iter().map(|k| k.name()))
            .collect();
        Err(AugmentError::UnknownName {
            what: "manipulation or degradation",
            name: name.to_string(),
            expected: names.join(", "),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_both_families_and_rejects_bad_specs_clearly() {
        assert_eq!(
            "contrast:-0.25".parse::<ImageOp>(),
            Ok(ImageOp::Manipulate(Manipulation::Contrast, -0.25))
        );
        assert_eq!(
            "identity".parse::<ImageOp>(),
            Ok(ImageOp::Manipulate(Manipulation::Identity, 0.0))
        );
        assert_eq!(
            "poisson:100".parse::<ImageOp>(),
            Ok(ImageOp::Degrade(
                Degradation::new(DegradationKind::Poisson, 100.0).unwrap()
            ))
        );
        let op: ImageOp = "speckle".parse().unwrap();
        assert_eq!(op.to_string(), "speckle:0.4");

        let msg = |s: &str| s.parse::<ImageOp>().unwrap_err().to_string();
        let m = msg("vignette:0.3");
        assert!(
            m.contains("`vignette`") && m.contains("brightness") && m.contains("speckle"),
            "{m}"
        );
        let m = msg("hue:0.75");
        assert!(
            m.contains("hue p = 0.75") && m.contains("[-0.5, 0.5]"),
            "{m}"
        );
        let m = msg("brightness:2");
        assert!(m.contains("[-1, 1]"), "{m}");
        let m = msg("saturation");
        assert!(m.contains("needs its intensity"), "{m}");
        let m = msg("gaussian:-1");
        assert!(m.contains("gaussian q = -1"), "{m}");
        let m = msg("sharpness:abc");
        assert!(m.contains("not a number"), "{m}");
        let m = msg("identity:0.2");
        assert!(m.contains("identity p = 0.2"), "{m}");
    }
}
