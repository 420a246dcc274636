//! Simulator benchmark: how long the default scene takes to prepare, render (49 views at
//! 400×300, 4 spp) and sample ground truth for (0.2 mm), and rays per second, against peers
//! measured in the same run: the same rig with no optional effect (unlit albedo), and with
//! shadows and highlights on (primary + shadow rays).
//!
//! Run: `cargo bench --bench sim` (about a minute on 2 cores). `SIM_BENCH_QUICK=1` renders 9 views
//! and samples ground truth at 0.5 mm instead.

use neus_aug::sim::desc::{Shadows, Specular};
use neus_aug::sim::setup::{crease_normals, Tracer};
use neus_aug::sim::{builtin, shapes, Counters, SceneDescription, SimScene, DEFAULT_SCENE};
use std::time::Instant;

fn render(desc: &SceneDescription) -> (f64, Counters) {
    let scene = SimScene::prepare(desc).expect("prepare");
    let t = Instant::now();
    let c: Counters = (0..scene.cameras.len())
        .map(|i| scene.render_view(i).counters)
        .sum();
    (t.elapsed().as_secs_f64(), c)
}

fn main() {
    let quick = std::env::var_os("SIM_BENCH_QUICK").is_some();
    let mut desc = builtin(DEFAULT_SCENE).unwrap();
    if quick {
        desc.rig.views = 9;
        desc.gt.spacing_mm = 0.5;
    }
    println!(
        "default scene '{}': {} views {}x{}, {} spp, ground truth at {} mm, {} threads",
        desc.name,
        desc.rig.views,
        desc.rig.resolution[0],
        desc.rig.resolution[1],
        desc.render.spp,
        desc.gt.spacing_mm,
        rayon::current_num_threads()
    );

    // Preparation, step by step.
    let t = Instant::now();
    let mesh = shapes::procedural(desc.object.shape.unwrap());
    let t_mesh = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let closed = mesh.is_closed_oriented();
    let t_closed = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let scene = SimScene::prepare(&desc).unwrap();
    let t_prepare = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let _tracer = Tracer::new(&scene.object_tris);
    let t_bvh = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let _n = crease_normals(
        &scene.object_tris,
        &scene.mesh_world.faces,
        scene.mesh_world.vertices.len(),
        30.0,
    );
    let t_normals = t.elapsed().as_secs_f64();
    println!(
        "prepare: {t_prepare:.3} s in all ({} faces; mesh {t_mesh:.3} s, closed check {t_closed:.3} s \
         [{closed}], BVH {t_bvh:.3} s, crease normals {t_normals:.3} s)",
        scene.mesh_world.faces.len()
    );

    let (t_default, c_default) = render(&desc);
    let rays = (c_default.primary_rays + c_default.shadow_rays) as f64;
    println!(
        "render default: {t_default:.2} s, {:.2} M primary rays, {:.2} M rays/s, {:.1} ms per view",
        c_default.primary_rays as f64 / 1e6,
        rays / t_default / 1e6,
        1e3 * t_default / desc.rig.views as f64
    );

    let mut plain = desc.clone();
    plain.effects = Default::default();
    let (t_plain, c_plain) = render(&plain);
    println!(
        "peer, no effects (unlit constant albedo): {t_plain:.2} s, {:.2} M rays/s; default / peer = {:.2}x",
        c_plain.primary_rays as f64 / t_plain / 1e6,
        t_default / t_plain
    );

    let mut heavy = desc.clone();
    heavy.effects.shadows = Some(Shadows::default());
    heavy.effects.specular = Some(Specular::default());
    let (t_heavy, c_heavy) = render(&heavy);
    println!(
        "peer, + shadows + specular: {t_heavy:.2} s, {:.2} M shadow rays, {:.2} M rays/s (primary + shadow); \
         heavy / default = {:.2}x",
        c_heavy.shadow_rays as f64 / 1e6,
        (c_heavy.primary_rays + c_heavy.shadow_rays) as f64 / t_heavy / 1e6,
        t_heavy / t_default
    );

    let t = Instant::now();
    let gt = scene.ground_truth();
    let t_gt = t.elapsed().as_secs_f64();
    println!(
        "ground truth: {t_gt:.2} s, {} samples -> {} visible points, {:.2} M occlusion rays, \
         {} back-facing skips; ObsMask: {} band voxels tested with {:.2} M rays, {} observed; \
         {:.2} M rays/s overall",
        gt.stats.sampled,
        gt.stats.visible,
        gt.stats.occlusion_rays as f64 / 1e6,
        gt.stats.backfacing_skips,
        gt.stats.obs_tested,
        gt.stats.obs_rays as f64 / 1e6,
        gt.stats.obs_voxels,
        (gt.stats.occlusion_rays + gt.stats.obs_rays) as f64 / t_gt / 1e6
    );
    println!(
        "default scene total (prepare + render + ground truth, without writing): {:.2} s",
        t_prepare + t_default + t_gt
    );
}
