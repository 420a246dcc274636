//! The built-in scenes: nine objects that span what makes DTU hard, each with a distinct scan
//! number (101–106) for its ground-truth file names.
//!
//! | name     | scan | what it tests                                                     |
//! |----------|------|-------------------------------------------------------------------|
//! | `blob`   | 101  | smooth genus-0 surface; the default (`default` is an alias)        |
//! | `torus`  | 102  | genus 1: a hole the cameras see through                            |
//! | `thin`   | 103  | rods and a fin ~1.5 % of the object's size                         |
//! | `blocks` | 104  | planar faces, sharp edges, highlights, shadows on a ground plane   |
//! | `cup`    | 105  | a deep concavity (122 mm deep, 55 mm inner radius)                 |
//! | `relief` | 106  | fine relief (0.6–2.2 mm ripples, domes, grooves) under raking light |
//! | `double-torus` | 107 | genus 2: two holes the cameras see through                |
//! | `plate`  | 108  | a thin sheet: a bent plate 3 mm thick (~2 % of its size)           |
//! | `rods`   | 109  | thin rods: a cube frame of 4 mm rods (genus 5, ~3 % of the size)   |
//!
//! The last three form the hard suite with `torus` and `thin`: holes that must open, parts thinner
//! than a few training pixels.
//!
//! Every scene is textured (the multiscale procedural albedo) and Lambert-shaded. The default
//! (`blob`) is built to be reconstructable by a CPU NeuS in minutes: smooth, genus 0, richly
//! textured, with masks, Lambertian shading and a mild ambient term, and no specular, shadows or
//! degradations.

use super::desc::{
    GroundPlane, Pattern, SceneDescription, Shading, ShadingModel, Shadows, Shape, Specular,
    Texture,
};
use super::SimError;

/// The name of the embedded default scene (what `neus-aug reconstruct` uses with no argument).
pub const DEFAULT_SCENE: &str = "blob";

/// One line of the catalog.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CatalogEntry {
    /// The name `neus-aug synth <name>` accepts.
    pub name: &'static str,
    /// DTU-style scan number.
    pub scan: u32,
    /// What the scene tests.
    pub summary: &'static str,
}

/// The catalog, in scan order.
pub const CATALOG: [CatalogEntry; 9] = [
    CatalogEntry {
        name: "blob",
        scan: 101,
        summary: "smooth genus-0 blob, textured, Lambertian (the default scene)",
    },
    CatalogEntry {
        name: "torus",
        scan: 102,
        summary: "leaning torus (genus 1) with shadows; the cameras see through the hole",
    },
    CatalogEntry {
        name: "thin",
        scan: 103,
        summary: "round body with seven 3 mm rods and a 2.5 mm fin (~1.5% of the size)",
    },
    CatalogEntry {
        name: "blocks",
        scan: 104,
        summary:
            "slab, cube, pyramid and prism: planar faces, sharp edges, highlights, ground plane",
    },
    CatalogEntry {
        name: "cup",
        scan: 105,
        summary: "deep cup (122 mm deep): a concavity with shadows inside",
    },
    CatalogEntry {
        name: "relief",
        scan: 106,
        summary:
            "leaning plaque with 0.6-2.2 mm relief (ripples, domes, grooves) under raking light",
    },
    CatalogEntry {
        name: "double-torus",
        scan: 107,
        summary: "two fused tori (genus 2) leaning so the cameras see through both holes",
    },
    CatalogEntry {
        name: "plate",
        scan: 108,
        summary: "a bent plate 3 mm thick (a thin sheet, ~2% of its size), tilted 40 degrees",
    },
    CatalogEntry {
        name: "rods",
        scan: 109,
        summary: "cube frame of twelve 4 mm rods (genus 5, ~3% of the size)",
    },
];

fn textured(scale_mm: f32) -> Option<Texture> {
    Some(Texture {
        enabled: true,
        pattern: Pattern::Multiscale,
        scale_mm,
    })
}

fn lambert(direction: [f64; 3], ambient: f32, diffuse: f32) -> Option<Shading> {
    Some(Shading {
        enabled: true,
        model: ShadingModel::Lambert,
        direction,
        ambient,
        diffuse,
        smooth_normals: true,
    })
}

/// The description of built-in scene `name` (`default` is an alias of [`DEFAULT_SCENE`]).
pub fn builtin(name: &str) -> Result<SceneDescription, SimError> {
    let name = if name == "default" {
        DEFAULT_SCENE
    } else {
        name
    };
    let entry = CATALOG
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| SimError::UnknownScene {
            name: name.into(),
            known: CATALOG
                .iter()
                .map(|e| e.name)
                .collect::<Vec<_>>()
                .join(", "),
        })?;
    let mut d = SceneDescription {
        name: entry.name.into(),
        scan: entry.scan,
        summary: entry.summary.into(),
        ..SceneDescription::default()
    };
    let e = &mut d.effects;
    let front_light = [-0.4, -0.5, 0.77];
    match entry.name {
        "blob" => {
            d.object.shape = Some(Shape::Blob);
            e.shading = lambert(front_light, 0.35, 0.7);
            e.texture = textured(16.0);
        }
        "torus" => {
            d.object.shape = Some(Shape::Torus);
            e.shading = lambert(front_light, 0.3, 0.75);
            e.shadows = Some(Shadows::default());
            e.texture = textured(14.0);
        }
        "thin" => {
            d.object.shape = Some(Shape::Thin);
            e.shading = lambert(front_light, 0.35, 0.7);
            e.texture = textured(10.0);
        }
        "blocks" => {
            d.object.shape = Some(Shape::Blocks);
            e.shading = lambert([-0.5, -0.35, 0.8], 0.25, 0.8);
            e.specular = Some(Specular::default());
            e.shadows = Some(Shadows::default());
            e.texture = textured(16.0);
            e.ground_plane = Some(GroundPlane::default());
        }
        "cup" => {
            d.object.shape = Some(Shape::Cup);
            e.shading = lambert([0.3, -0.45, 0.85], 0.3, 0.75);
            e.shadows = Some(Shadows::default());
            e.texture = textured(14.0);
        }
        "relief" => {
            d.object.shape = Some(Shape::Relief);
            // Raking light from the left, low over the plaque's face, brings the relief out.
            e.shading = lambert([-0.9, -0.35, 0.3], 0.3, 0.8);
            e.shadows = Some(Shadows::default());
            e.texture = textured(12.0);
        }
        "double-torus" => {
            d.object.shape = Some(Shape::DoubleTorus);
            e.shading = lambert(front_light, 0.3, 0.75);
            e.shadows = Some(Shadows::default());
            e.texture = textured(14.0);
        }
        "plate" => {
            d.object.shape = Some(Shape::Plate);
            e.shading = lambert(front_light, 0.35, 0.7);
            e.texture = textured(12.0);
        }
        "rods" => {
            d.object.shape = Some(Shape::Rods);
            e.shading = lambert(front_light, 0.35, 0.7);
            e.texture = textured(10.0);
        }
        _ => unreachable!("every catalog entry has a description"),
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_is_valid_distinct_and_round_trips_through_toml() {
        let mut scans = std::collections::BTreeSet::new();
        for e in &CATALOG {
            let d = builtin(e.name).unwrap();
            d.validate().unwrap();
            assert_eq!(d.name, e.name);
            assert!(scans.insert(d.scan));
            assert!(d.effects.texture().is_some(), "{} is untextured", e.name);
            let back = SceneDescription::from_toml_str(&d.to_toml(), "<test>", None).unwrap();
            assert_eq!(back, d);
        }
        assert_eq!(builtin("default").unwrap(), builtin(DEFAULT_SCENE).unwrap());
        let d = builtin(DEFAULT_SCENE).unwrap();
        assert!(d.effects.specular.is_none() && d.effects.shadows.is_none());
        assert!(d.effects.degrade.is_empty() && d.effects.exposure.is_none());
        let err = builtin("teapot").unwrap_err().to_string();
        assert!(
            err.contains("teapot") && err.contains("blob, torus"),
            "{err}"
        );
    }
}
