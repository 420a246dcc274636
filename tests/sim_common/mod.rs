//! Helpers shared by the simulator's integration tests (`tests/sim_*.rs`).
#![allow(dead_code)]

use neus_aug::sim::{builtin, Counters, SceneDescription, SimScene, ViewRender};

/// A built-in scene shrunk for tests: `w × h` pixels, `views` views, `spp` samples, ground truth
/// at `spacing` mm.
pub fn small(name: &str, w: u32, h: u32, views: usize, spp: u32, spacing: f64) -> SceneDescription {
    let mut d = builtin(name).expect("built-in scene");
    d.rig.resolution = [w, h];
    d.rig.views = views;
    d.render.spp = spp;
    d.gt.spacing_mm = spacing;
    d
}

/// Every view of a description, and the summed counters.
pub fn render_all(desc: &SceneDescription) -> (Vec<ViewRender>, Counters) {
    let scene = SimScene::prepare(desc).expect("prepare");
    let views: Vec<ViewRender> = (0..scene.cameras.len())
        .map(|i| scene.render_view(i))
        .collect();
    let total = views.iter().map(|v| v.counters).sum();
    (views, total)
}

/// Number of image values that differ between two renders of the same rig.
pub fn differing_values(a: &[ViewRender], b: &[ViewRender]) -> usize {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            x.image
                .data
                .iter()
                .zip(&y.image.data)
                .filter(|(p, q)| p.to_bits() != q.to_bits())
                .count()
        })
        .sum()
}

/// True when images and masks are bit-identical.
pub fn bit_identical(a: &[ViewRender], b: &[ViewRender]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            x.image
                .data
                .iter()
                .map(|v| v.to_bits())
                .eq(y.image.data.iter().map(|v| v.to_bits()))
                && x.mask.data.iter().map(|v| v.to_bits()).eq(y
                    .mask
                    .data
                    .iter()
                    .map(|v| v.to_bits()))
        })
}

/// Runs the `python3` interpreter if there is one; `None` (after printing why) otherwise.
pub fn python() -> Option<&'static str> {
    let ok = std::process::Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!("SKIPPED: python3 is not installed, the scipy cross-check cannot run");
    }
    ok.then_some("python3")
}
