use neus_aug::reconstruct::seen_floor::{seen_floor, SeenRule};
use neus_aug::scene::{LoadOptions, Scene};
use std::path::Path;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let dir = Path::new(&a[1]);
    let held: Vec<usize> = a[2].split(',').map(|s| s.parse().unwrap()).collect();
    let scene = Scene::load(dir, &LoadOptions::default()).unwrap();
    let cams: Vec<_> = scene
        .views
        .iter()
        .filter(|v| !held.contains(&v.index))
        .map(|v| &v.camera)
        .collect();
    let truth = neus_aug::sim::SceneTruth::read(dir);
    let gt = dtu_eval::protocol::GroundTruth::load(dir, truth.scan.unwrap()).unwrap();
    let mesh = dtu_eval::ply::read_mesh(&dir.join("gt_mesh.ply")).unwrap();
    let f = truth.floor.unwrap();
    for k in [1usize, 2] {
        let r = seen_floor(
            &mesh,
            &scene.normalization,
            &cams,
            &SeenRule {
                min_views: k,
                margin_mm: 0.0,
                min_area_share: 0.02,
            },
            &gt,
            &dtu_eval::report::DtuParams::default(),
            0,
        )
        .unwrap()
        .unwrap();
        println!(
            "{} floor {:.3} ({:.3}/{:.3}) min{k}: {:.3} ({:.3}/{:.3}) cut {:.3}",
            dir.display(),
            f.chamfer_sum,
            f.mean_d2s,
            f.mean_s2d,
            r.chamfer_sum,
            r.mean_d2s,
            r.mean_s2d,
            r.area_share_cut
        );
    }
}
