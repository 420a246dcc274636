//! End-to-end smoke check of the pieces together: a tiny model fitted with AdamW to a constant
//! coloured target lowers its colour loss, keeps every parameter finite, and the occupancy grid
//! updates along the way.

mod field_common;

use field_common::{batch, tiny_config};
use neus_aug::render::NeusModel;
use neus_aug::train::{AdamW, AdamWConfig, Targets, TrainStep};

#[test]
fn a_few_steps_lower_the_loss() {
    let mut cfg = tiny_config();
    cfg.render.occupancy.resolution = 16;
    cfg.render.occupancy.warmup_steps = 8;
    cfg.render.occupancy.update_every = 4;
    let model = NeusModel::new(cfg).unwrap();
    let mut p = model.init_params(11);
    let mut opt = AdamW::new(AdamWConfig::default(), p.len());
    let mut occ = model.new_occupancy_grid();
    let b = batch(64, 21);
    let target = vec![[0.2f32, 0.6, 0.3]; b.origins.len()];
    let rays = b.rays();
    let t = Targets {
        rgb: &target,
        mask: None,
    };
    let mut first = None;
    let mut last = 0.0;
    for step in 0..60u64 {
        let sched = model.config.schedule(step);
        model.update_occupancy(&p, &mut occ, step, sched, 5);
        let mut g = vec![0f32; p.len()];
        let out = model
            .train_step(&p, &mut g, &rays, &t, sched, Some(&occ), step)
            .unwrap();
        first.get_or_insert(out.rgb_l1);
        last = out.rgb_l1;
        opt.step(&mut p, &g, &model.layout, 1.0).unwrap();
    }
    let first = first.unwrap();
    assert!(p.iter().all(|v| v.is_finite()));
    assert!(last < 0.5 * first, "L1 {first} -> {last}");
}
