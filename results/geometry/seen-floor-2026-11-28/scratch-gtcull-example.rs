//! scratch: GT mesh cut by rule 4 at 1,2,3 views; gtcull SCENE HELD(comma) OUTPREFIX
use neus_aug::mesh::clean::cull_unseen;
use neus_aug::scene::dtu::{LoadOptions, Scene};
use std::path::Path;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let scene = Scene::load(Path::new(&a[1]), &LoadOptions::default()).unwrap();
    let held: Vec<usize> = a[2].split(',').map(|s| s.parse().unwrap()).collect();
    let gp = std::env::var("GT").map(std::path::PathBuf::from).unwrap_or(Path::new(&a[1]).join("gt_mesh.ply"));
    let mut gt = dtu_eval::ply::read_mesh(&gp).unwrap();
    let n = &scene.normalization;
    for v in &mut gt.vertices {
        let p = n.to_normalized([v[0] as f64, v[1] as f64, v[2] as f64]);
        *v = [p[0] as f32, p[1] as f32, p[2] as f32];
    }
    let cams: Vec<_> = scene.views.iter().filter(|v| !held.contains(&v.index)).map(|v| &v.camera).collect();
    println!("train cams {}", cams.len());
    for k in [1usize, 2, 3] {
        let (mut m, un) = cull_unseen(&gt, &cams, k, 0.0);
        println!("min {k}: unseen faces {un} of {}", gt.faces.len());
        neus_aug::mesh::extract::to_world(&mut m, n);
        dtu_eval::ply::write_mesh(Path::new(&format!("{}_min{k}.ply", a[3])), &m).unwrap();
    }
}
