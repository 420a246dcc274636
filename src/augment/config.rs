//! The augmentation configuration: mode, SIA intensities, DIA widths, the identity option, seed.
//! Every field has a documented default (justified in the module docs of [`crate::augment`]); TOML
//! tables reject unknown keys so a typo is an error, not a silently ignored setting.

use super::{normalise_name, range_text, AugmentError, Manipulation};
use std::fmt;
use std::str::FromStr;

/// Which augmentation trains the model (paper §3).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum AugMode {
    /// The baseline: original images, identity code, `p = 0`.
    #[default]
    None,
    /// Static image augmentation: six precomputed replicas, embedding `Emb(M)`.
    Sia,
    /// Dynamic image augmentation: a random manipulation and `p` per ray, embedding `[Emb(M), p]`.
    Dia,
}

impl AugMode {
    /// The name on the command line and in config files.
    pub fn name(self) -> &'static str {
        match self {
            AugMode::None => "none",
            AugMode::Sia => "sia",
            AugMode::Dia => "dia",
        }
    }
}

impl fmt::Display for AugMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for AugMode {
    type Err = AugmentError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match normalise_name(s).as_str() {
            "none" => Ok(AugMode::None),
            "sia" => Ok(AugMode::Sia),
            "dia" => Ok(AugMode::Dia),
            _ => Err(AugmentError::UnknownName {
                what: "augmentation mode",
                name: s.to_string(),
                expected: "none, sia, dia".into(),
            }),
        }
    }
}

/// SIA's fixed intensity `p_i` per manipulation (one replica each).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SiaIntensities {
    /// Factor `1 + p`; default −0.3 (×0.7, darker; never clips).
    pub brightness: f32,
    /// Factor `1 + p`; default −0.3 (30 % towards the mean gray; never clips).
    pub contrast: f32,
    /// Factor `1 + p`; default −0.4 (40 % towards gray; never clips).
    pub saturation: f32,
    /// Turns; default +0.1 (36°; hue rotation never clips).
    pub hue: f32,
    /// Factor `1 + p`; default +1.0 (factor 2, sharpened; clips only at strong edges).
    pub sharpness: f32,
}

impl Default for SiaIntensities {
    fn default() -> Self {
        Self {
            brightness: -0.3,
            contrast: -0.3,
            saturation: -0.4,
            hue: 0.1,
            sharpness: 1.0,
        }
    }
}

impl SiaIntensities {
    /// `p_i` of `m`; 0 for the identity.
    pub fn get(&self, m: Manipulation) -> f32 {
        match m {
            Manipulation::Identity => 0.0,
            Manipulation::Brightness => self.brightness,
            Manipulation::Contrast => self.contrast,
            Manipulation::Saturation => self.saturation,
            Manipulation::Hue => self.hue,
            Manipulation::Sharpness => self.sharpness,
        }
    }
}

/// DIA's width `w_i` per manipulation: `p ~ U[-w_i/2, w_i/2)`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DiaWidths {
    /// Default 0.8: factors in `[0.6, 1.4]` (torchvision `ColorJitter(brightness=0.4)`).
    pub brightness: f32,
    /// Default 0.8: factors in `[0.6, 1.4]`.
    pub contrast: f32,
    /// Default 0.8: factors in `[0.6, 1.4]`.
    pub saturation: f32,
    /// Default 0.2: ±0.1 turn (torchvision `ColorJitter(hue=0.1)`).
    pub hue: f32,
    /// Default 2.0: factors in `[0, 2]` (torchvision `RandomAdjustSharpness(2)` range).
    pub sharpness: f32,
}

impl Default for DiaWidths {
    fn default() -> Self {
        Self {
            brightness: 0.8,
            contrast: 0.8,
            saturation: 0.8,
            hue: 0.2,
            sharpness: 2.0,
        }
    }
}

impl DiaWidths {
    /// `w_i` of `m`; 0 for the identity.
    pub fn get(&self, m: Manipulation) -> f32 {
        match m {
            Manipulation::Identity => 0.0,
            Manipulation::Brightness => self.brightness,
            Manipulation::Contrast => self.contrast,
            Manipulation::Saturation => self.saturation,
            Manipulation::Hue => self.hue,
            Manipulation::Sharpness => self.sharpness,
        }
    }
}

/// The augmentation settings; the TOML table `[augment]` of a run's config.
///
/// ```toml
/// [augment]
/// mode = "dia"              # none | sia | dia
/// include_identity = false  # DIA only: also draw the identity (trains the test-time code)
/// seed = 0                  # the augmentation's own random stream
/// [augment.sia_p]           # SIA intensities p_i (any subset of the five)
/// hue = 0.1
/// [augment.dia_width]       # DIA widths w_i (any subset of the five)
/// sharpness = 2.0
/// ```
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AugmentConfig {
    /// Default `none` (the baseline).
    pub mode: AugMode,
    /// SIA intensities; used when `mode = "sia"`.
    pub sia_p: SiaIntensities,
    /// DIA widths; used when `mode = "dia"`.
    pub dia_width: DiaWidths,
    /// DIA only. Default `false`, the paper's DIA: the identity is never drawn, so its embedding
    /// row (code 0, the one used at test time) keeps its zero initialisation. `true` draws it as
    /// a sixth choice with `p = 0`, so the test-time code is trained (see the module docs).
    pub include_identity: bool,
    /// Seed of the augmentation's random stream ([`Self::rng`]), default 0. Kept apart from the
    /// ray sampler's stream so `none`, `sia` and `dia` runs with the same training seed visit the
    /// same pixels in the same order.
    pub seed: u64,
}

impl AugmentConfig {
    /// Checks every intensity and width: `p_i` within [`Manipulation::p_range`], `w_i ≥ 0` with
    /// `w_i/2` within the range too. The error names the key, e.g. `augment.dia_width.hue`.
    pub fn validate(&self) -> Result<(), AugmentError> {
        for m in Manipulation::NON_IDENTITY {
            let (lo, hi) = m.p_range();
            let p = self.sia_p.get(m);
            if !(p.is_finite() && (lo..=hi).contains(&p)) {
                return Err(AugmentError::OutOfRange {
                    what: format!("augment.sia_p.{}", m.name()),
                    value: p.to_string(),
                    range: range_text(lo as f64, true, hi as f64, true),
                });
            }
            let w = self.dia_width.get(m);
            let w_max = 2.0 * hi.min(-lo);
            if !(w.is_finite() && (0.0..=w_max).contains(&w)) {
                return Err(AugmentError::OutOfRange {
                    what: format!("augment.dia_width.{}", m.name()),
                    value: w.to_string(),
                    range: range_text(0.0, true, w_max as f64, true),
                });
            }
        }
        Ok(())
    }

    /// The augmentation's own RNG, seeded from [`Self::seed`].
    pub fn rng(&self) -> rand_pcg::Pcg64Mcg {
        rand::SeedableRng::seed_from_u64(self.seed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_round_trip_through_toml() {
        let cfg = AugmentConfig::default();
        cfg.validate().unwrap();
        assert_eq!(cfg.mode, AugMode::None);
        assert!(!cfg.include_identity);
        let text = toml::to_string(&cfg).unwrap();
        let back: AugmentConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, cfg);
    }

    #[test]
    fn partial_tables_keep_the_other_defaults() {
        let cfg: AugmentConfig =
            toml::from_str("mode = \"dia\"\n[dia_width]\nhue = 0.5\n[sia_p]\nbrightness = 0.2\n")
                .unwrap();
        assert_eq!(cfg.mode, AugMode::Dia);
        assert_eq!(cfg.dia_width.hue, 0.5);
        assert_eq!(cfg.dia_width.brightness, DiaWidths::default().brightness);
        assert_eq!(cfg.sia_p.brightness, 0.2);
        assert_eq!(cfg.sia_p.hue, SiaIntensities::default().hue);
        cfg.validate().unwrap();
    }

    #[test]
    fn unknown_keys_and_bad_values_are_errors_naming_the_key() {
        let err = toml::from_str::<AugmentConfig>("mode = \"dia\"\nwidth = 2\n").unwrap_err();
        assert!(err.to_string().contains("width"), "{err}");
        let err = toml::from_str::<AugmentConfig>("[dia_width]\nblur = 1\n").unwrap_err();
        assert!(err.to_string().contains("blur"), "{err}");
        let err = toml::from_str::<AugmentConfig>("mode = \"both\"\n").unwrap_err();
        assert!(err.to_string().contains("both"), "{err}");

        let mut cfg = AugmentConfig::default();
        cfg.dia_width.hue = 1.5;
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.contains("augment.dia_width.hue = 1.5") && err.contains("[0, 1]"),
            "{err}"
        );
        let mut cfg = AugmentConfig::default();
        cfg.sia_p.contrast = -1.5;
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.contains("augment.sia_p.contrast") && err.contains("[-1, 1]"),
            "{err}"
        );
        let mut cfg = AugmentConfig::default();
        cfg.dia_width.brightness = -0.1;
        assert!(cfg.validate().is_err());
        cfg.dia_width.brightness = f32::NAN;
        assert!(cfg.validate().is_err());
    }

    #[test]
    fn mode_names() {
        for m in [AugMode::None, AugMode::Sia, AugMode::Dia] {
            assert_eq!(m.to_string().parse::<AugMode>(), Ok(m));
        }
        assert_eq!("DIA".parse::<AugMode>(), Ok(AugMode::Dia));
        let err = "all".parse::<AugMode>().unwrap_err().to_string();
        assert!(
            err.contains("`all`") && err.contains("none, sia, dia"),
            "{err}"
        );
    }
}
