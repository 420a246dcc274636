//! Marching cubes at 512³ on an analytic sphere (the `sphere` shape of `mesh::sdf`, radius 0.61
//! in `[-1, 1]^3`), against `isosurface` 0.1.0-alpha.0 measured in the same run.
//!
//! Timed separately:
//! - `grid_eval`: sampling the SDF on the whole grid (`sample_grid`, parallel batches);
//! - `extract`: marching cubes on the grid already in memory (`marching_cubes_values`), the figure
//!   comparable to scikit-image's and PyMCubes' `marching_cubes(volume, 0)`;
//! - `streaming`: SDF evaluation and extraction together, slab by slab (`marching_cubes` with the
//!   closure), the production path;
//! - `isosurface`: the oracle crate on the same grid values (single-threaded, cubic grids only; its
//!   z axis samples one extra plane outside the box, which the sphere does not reach).
//!
//! Usage: `cargo bench -p neus-aug --bench mcubes -- [--res N] [--repeats R] [--no-oracle]`.
//! Each figure is the best of R runs (default 3; the oracle runs once). Lines starting with
//! `RESULT` are read by `scripts/bench_mcubes.py`, which adds scikit-image and PyMCubes.

use isosurface::distance::Signed;
use isosurface::extractor::IndexedVertices;
use isosurface::math::Vec3;
use isosurface::sampler::Sampler;
use isosurface::source::ScalarSource;
use isosurface::MarchingCubes;
use neus_aug::mesh::sdf::Shape;
use neus_aug::mesh::{marching_cubes, marching_cubes_values, sample_grid, GridSpec, McOptions};
use std::time::Instant;

struct Grid<'a> {
    values: &'a [f32],
    n: usize,
}

impl ScalarSource for Grid<'_> {
    fn sample_scalar(&self, p: Vec3) -> Signed {
        let idx =
            [p.x, p.y, p.z].map(|c| ((c * (self.n - 1) as f32).round() as usize).min(self.n - 1));
        Signed(self.values[(idx[2] * self.n + idx[1]) * self.n + idx[0]])
    }
}

fn best_of<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("at least one run"))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let flag = |name: &str| args.iter().position(|a| a == name);
    let value = |name: &str, default: usize| {
        flag(name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let res = value("--res", 512);
    let repeats = value("--repeats", 3);
    let oracle = flag("--no-oracle").is_none();

    let shape = Shape::named("sphere").expect("built-in shape");
    let sdf = move |p: &[[f32; 3]]| shape.eval_batch(p);
    let grid = GridSpec::cube([-1.0; 3], [1.0; 3], res);
    let opts = McOptions::default();
    println!(
        "marching cubes on the analytic sphere at {res}^3, {} rayon threads, best of {repeats}",
        rayon::current_num_threads()
    );

    let (t_eval, values) = best_of(repeats, || sample_grid(&sdf, &grid, &opts).expect("grid"));
    let (t_extract, mesh) = best_of(repeats, || {
        marching_cubes_values(&values, &grid, 0.0).expect("extract")
    });
    let (t_stream, streamed) = best_of(repeats, || marching_cubes(&sdf, &grid, &opts).expect("mc"));
    assert_eq!(
        mesh, streamed,
        "streaming and in-memory extraction must agree"
    );
    let (nv, nf) = (mesh.vertices.len(), mesh.faces.len());
    println!("RESULT grid_eval {t_eval:.4} 0 0");
    println!("RESULT extract {t_extract:.4} {nv} {nf}");
    println!("RESULT streaming {t_stream:.4} {nv} {nf}");
    println!("  grid evaluation (sample_grid)        {t_eval:8.3} s");
    println!(
        "  extraction only (values in memory)   {t_extract:8.3} s   {nv} vertices, {nf} faces"
    );
    println!("  streaming (SDF + extraction, slabs)  {t_stream:8.3} s");

    if oracle {
        // The oracle samples res × res × (res + 1) points; the extra z plane lies past the box and
        // outside the sphere, so it reads the last plane again (clamped index) — same surface.
        let src = Grid {
            values: &values,
            n: res,
        };
        let (t_oracle, (ov, of)) = best_of(1, || {
            let (mut v, mut idx) = (Vec::new(), Vec::new());
            MarchingCubes::<Signed>::new(res).extract(
                &Sampler::new(&src),
                &mut IndexedVertices::new(&mut v, &mut idx),
            );
            (v.len() / 3, idx.len() / 3)
        });
        println!("RESULT isosurface {t_oracle:.4} {ov} {of}");
        println!(
            "  isosurface 0.1.0-alpha.0 (1 thread)  {t_oracle:8.3} s   {ov} vertices, {of} faces"
        );
        println!(
            "  ratio isosurface / extraction: {:.1}x   isosurface / streaming: {:.1}x",
            t_oracle / t_extract,
            t_oracle / t_stream
        );
    }
}
