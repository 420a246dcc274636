//! Effects are honest: for every effect, a scene without it renders bit-identically to the same
//! scene with the effect switched off (`enabled = false`), does none of that effect's work (its
//! counter stays 0 and every other counter is unchanged), and switching it on changes pixels
//! (never the masks) and does that work.

mod sim_common;

use neus_aug::sim::desc::{
    Exposure, GroundPlane, LightJitter, ShadingModel, Shadows, Specular, Texture,
};
use neus_aug::sim::{Counters, SceneDescription, SimScene};
use sim_common::{bit_identical, differing_values, render_all, small};

/// The default scene, tiny: 48×36, 3 views, 4 samples per pixel.
fn base() -> SceneDescription {
    small("blob", 48, 36, 3, 4, 1.0)
}

struct Case {
    name: &'static str,
    without: SceneDescription,
    off: Vec<SceneDescription>,
    on: SceneDescription,
    work: fn(&Counters) -> u64,
    /// At least this many image values must change when the effect is on.
    min_changed: usize,
}

fn check(case: Case) {
    let (r_without, c_without) = render_all(&case.without);
    assert_eq!(
        (case.work)(&c_without),
        0,
        "{}: work done although the effect is absent: {c_without:?}",
        case.name
    );
    for (k, off) in case.off.iter().enumerate() {
        let (r_off, c_off) = render_all(off);
        assert!(
            bit_identical(&r_without, &r_off),
            "{}: switched-off variant {k} renders differently ({} values)",
            case.name,
            differing_values(&r_without, &r_off)
        );
        assert_eq!(
            c_off, c_without,
            "{}: switched-off variant {k} does different work",
            case.name
        );
    }
    let (r_on, c_on) = render_all(&case.on);
    assert!(
        (case.work)(&c_on) > 0,
        "{}: no work counted with the effect on: {c_on:?}",
        case.name
    );
    let changed = differing_values(&r_without, &r_on);
    assert!(
        changed >= case.min_changed,
        "{}: only {changed} values change with the effect on",
        case.name
    );
    assert_eq!(c_on.primary_rays, c_without.primary_rays);
    for (a, b) in r_without.iter().zip(&r_on) {
        assert_eq!(a.mask, b.mask, "{}: the effect changed a mask", case.name);
    }
}

#[test]
fn the_default_scene_does_no_optional_work() {
    let (_, c) = render_all(&base());
    assert_eq!(c.primary_rays, 3 * 48 * 36 * 4);
    assert!(c.object_hits > 0 && c.texture_evals == c.object_hits && c.lambert_evals > 0);
    assert_eq!(
        (
            c.shadow_rays,
            c.specular_evals,
            c.plane_hits,
            c.exposure_views,
            c.light_jitter_views,
            c.degrade_calls
        ),
        (0, 0, 0, 0, 0, 0),
        "{c:?}"
    );
}

#[test]
fn shading() {
    let mut without = base();
    without.effects.shading = None;
    let mut off = base();
    off.effects.shading.as_mut().unwrap().enabled = false;
    let mut albedo = base();
    albedo.effects.shading.as_mut().unwrap().model = ShadingModel::Albedo;
    check(Case {
        name: "shading",
        without,
        off: vec![off, albedo],
        on: base(),
        work: |c| c.lambert_evals + c.normal_interps,
        min_changed: 1000,
    });
}

#[test]
fn texture() {
    let mut without = base();
    without.effects.texture = None;
    let mut off = base();
    off.effects.texture = Some(Texture {
        enabled: false,
        ..Texture::default()
    });
    check(Case {
        name: "texture",
        without,
        off: vec![off],
        on: base(),
        work: |c| c.texture_evals,
        min_changed: 1000,
    });
}

#[test]
fn specular() {
    let mut off = base();
    off.effects.specular = Some(Specular {
        enabled: false,
        ..Specular::default()
    });
    let mut on = base();
    on.effects.specular = Some(Specular::default());
    check(Case {
        name: "specular",
        without: base(),
        off: vec![off],
        on,
        work: |c| c.specular_evals,
        min_changed: 20,
    });
}

#[test]
fn shadows() {
    // The blob casts its shadow on the ground plane.
    let mut without = base();
    without.effects.ground_plane = Some(GroundPlane::default());
    let mut off = without.clone();
    off.effects.shadows = Some(Shadows {
        enabled: false,
        ..Shadows::default()
    });
    let mut on = without.clone();
    on.effects.shadows = Some(Shadows::default());
    check(Case {
        name: "shadows",
        without,
        off: vec![off],
        on,
        work: |c| c.shadow_rays,
        min_changed: 50,
    });
}

#[test]
fn exposure() {
    let mut off = base();
    off.effects.exposure = Some(Exposure {
        enabled: false,
        ..Exposure::default()
    });
    let mut on = base();
    on.effects.exposure = Some(Exposure::default());
    check(Case {
        name: "exposure",
        without: base(),
        off: vec![off],
        on,
        work: |c| c.exposure_views,
        min_changed: 1000,
    });
}

#[test]
fn light_jitter() {
    let mut off = base();
    off.effects.light_jitter = Some(LightJitter {
        enabled: false,
        ..LightJitter::default()
    });
    let mut on = base();
    on.effects.light_jitter = Some(LightJitter::default());
    check(Case {
        name: "light_jitter",
        without: base(),
        off: vec![off],
        on,
        work: |c| c.light_jitter_views,
        min_changed: 1000,
    });
}

#[test]
fn ground_plane() {
    let mut off = base();
    off.effects.ground_plane = Some(GroundPlane {
        enabled: false,
        ..GroundPlane::default()
    });
    let mut on = base();
    on.effects.ground_plane = Some(GroundPlane::default());
    check(Case {
        name: "ground_plane",
        without: base(),
        off: vec![off],
        on,
        work: |c| c.plane_hits,
        min_changed: 1000,
    });
}

#[test]
fn one_effect_never_shifts_another_effects_random_draws() {
    let mut a = base();
    a.effects.exposure = Some(Exposure::default());
    let mut b = a.clone();
    b.effects.light_jitter = Some(LightJitter::default());
    b.effects.texture = None;
    let (sa, sb) = (
        SimScene::prepare(&a).unwrap(),
        SimScene::prepare(&b).unwrap(),
    );
    let mut c = Counters::default();
    let gains_a: Vec<f32> = (0..3).map(|i| sa.view_gain(i, &mut c).unwrap()).collect();
    let gains_b: Vec<f32> = (0..3).map(|i| sb.view_gain(i, &mut c).unwrap()).collect();
    assert_eq!(gains_a, gains_b);
    // Gains differ between views and depend on the seed.
    assert!(
        gains_a[0] != gains_a[1] && gains_a[1] != gains_a[2],
        "{gains_a:?}"
    );
    let mut seeded = a.clone();
    seeded.seed = 7;
    let s7 = SimScene::prepare(&seeded).unwrap();
    assert_ne!(s7.view_gain(0, &mut c), sa.view_gain(0, &mut c));
}

#[test]
fn degrade() {
    // An empty list is the switched-off form of this effect.
    let mut off = base();
    off.effects.degrade = Vec::new();
    for spec in [
        "gaussian:0.1",
        "motion-blur:5",
        "poisson:10",
        "salt-pepper:0.05",
        "speckle:0.4",
    ] {
        let mut on = base();
        on.effects.degrade = vec![spec.to_string()];
        check(Case {
            name: "degrade",
            without: base(),
            off: vec![off.clone()],
            on,
            work: |c| c.degrade_calls,
            min_changed: 200,
        });
    }
    // Two degradations run in order, one call each per view.
    let mut two = base();
    two.effects.degrade = vec!["motion-blur:2.5".into(), "gaussian:0.05".into()];
    let (_, c) = render_all(&two);
    assert_eq!(c.degrade_calls, 2 * 3);
}

#[test]
fn degradations_are_seeded_per_scene() {
    let mut a = base();
    a.effects.degrade = vec!["gaussian:0.1".into()];
    let mut b = a.clone();
    b.seed = 9;
    let (ra, _) = render_all(&a);
    let (ra2, _) = render_all(&a);
    let (rb, _) = render_all(&b);
    assert!(bit_identical(&ra, &ra2));
    assert!(differing_values(&ra, &rb) > 1000);
}
