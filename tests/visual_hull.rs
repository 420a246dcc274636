//! The visual-hull initialisation (`train::hull`) on a simulated torus: the hull holds
//! the true surface and keeps the hole open, and the fitted SDF network has the hull's sign.

use neus_aug::reconstruct::Preset;
use neus_aug::render::NeusModel;
use neus_aug::scene::{Camera, GrayImage, LoadOptions, Scene};
use neus_aug::sim;
use neus_aug::train::hull::{carve, fit, sphere_cover, HullSdf, InitConfig, InitKind};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// A small torus scene (16 views at 100×75) and its true mesh's vertices (normalised space).
fn torus() -> (tempfile::TempDir, Scene, Vec<[f32; 3]>) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("torus");
    let mut desc = sim::builtin("torus").unwrap();
    desc.rig.views = 16;
    desc.rig.resolution = [100, 75];
    desc.render.spp = 1;
    desc.gt.spacing_mm = 2.0;
    desc.gt.obs_res_mm = 4.0;
    sim::generate(&desc, &dir, &Default::default()).unwrap();
    let scene = Scene::load(&dir, &LoadOptions::default()).unwrap();
    let gt = dtu_eval::ply::read_mesh(&dir.join("gt_mesh.ply")).unwrap();
    let pts = gt
        .vertices
        .iter()
        .map(|v| {
            scene
                .normalization
                .to_normalized([v[0] as f64, v[1] as f64, v[2] as f64])
                .map(|c| c as f32)
        })
        .collect();
    (tmp, scene, pts)
}

#[test]
fn hull_holds_the_torus_keeps_its_hole_open_and_the_fit_takes_its_sign() {
    let (_tmp, scene, truth) = torus();
    let views: Vec<(&Camera, &GrayImage)> = scene
        .views
        .iter()
        .map(|v| (&v.camera, v.mask.as_ref().unwrap()))
        .collect();
    let (res, r) = (64usize, 1.0f32);
    let inside = carve(&views, r, res);
    let hull = HullSdf::from_occupancy(&inside, res, r).unwrap();
    let h = hull.voxel();
    // Every true surface point lies inside the hull, or within a voxel of its surface.
    let outside = truth.iter().filter(|&&p| hull.at(p) > h).count();
    assert!(
        outside == 0,
        "{outside} of {} true vertices outside the hull",
        truth.len()
    );
    // The hole: the centroid of a torus's vertices is the middle of its hole, which every view
    // that looks through it carves.
    let n = truth.len() as f32;
    let c = [0, 1, 2].map(|a| truth.iter().map(|p| p[a]).sum::<f32>() / n);
    assert!(hull.at(c) > 2.0 * h, "hole centre {c:?}: {}", hull.at(c));
    assert!(hull.inside_share() < 0.2, "{}", hull.inside_share());
    // The hole takes the middle of the init sphere: `sphere_or_hull` starts this torus from
    // the hull.
    let cover = sphere_cover(
        &inside,
        res,
        r,
        Preset::Fast.config().model.field.sdf.sphere_init_radius,
    );
    assert!(
        cover < InitConfig::default().sphere_cover_min,
        "cover {cover}"
    );

    // The fit: from the sphere init to the hull's sign at points away from its surface.
    let cfg = Preset::Fast.config();
    let model = NeusModel::new(cfg.model.clone()).unwrap();
    let mut params = model.init_params(0);
    let ic = InitConfig {
        kind: InitKind::VisualHull,
        steps: 150,
        points: 2048,
        ..InitConfig::default()
    };
    let active = model.config.schedule(0).active_levels;
    let sign_agreement = |params: &[f32]| {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let pts: Vec<[f32; 3]> = (0..4000)
            .map(|_| [0; 3].map(|_| rng.random_range(-0.9f32..0.9)))
            .filter(|&p| hull.at(p).abs() > 3.0 * h)
            .collect();
        let f = model.sdf(params, &pts, active);
        let agree = pts
            .iter()
            .zip(&f)
            .filter(|(p, f)| (hull.at(**p) > 0.0) == (**f > 0.0))
            .count();
        (
            agree as f64 / pts.len() as f64,
            model.sdf(params, &[c], active)[0],
        )
    };
    let before = sign_agreement(&params);
    let rep = fit(&model, &mut params, &hull, &ic, active, 0).unwrap();
    let after = sign_agreement(&params);
    assert!(rep.l1_last < 0.5 * rep.l1_first, "{rep:?}");
    assert!(after.0 > 0.97, "sign agreement {before:?} → {after:?}");
    assert!(
        after.1 > 0.0,
        "the hole centre is outside the fitted SDF: {after:?}"
    );
    assert!(params.iter().all(|v| v.is_finite()));
    // Seeded: the same fit again gives the same parameters.
    let mut again = model.init_params(0);
    fit(&model, &mut again, &hull, &ic, active, 0).unwrap();
    assert_eq!(again, params);
}
