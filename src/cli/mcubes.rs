//! `neus-aug mcubes` (hidden): marching cubes on an analytic SDF, for `scripts/crosscheck_mcubes.py`
//! and quick experiments. Writes the mesh as binary PLY (optionally mapped to world mm), the
//! sampled grid as `.npy` (`float32`, shape `[nz, ny, nx]`, so `arr[k, j, i]` is point
//! `(i, j, k)`), and prints one JSON line with counts, topology and timings.

use anyhow::{bail, Context};
use neus_aug::mesh::sdf::Shape;
use neus_aug::mesh::{
    extract_two_pass, marching_cubes, sample_grid, to_world, GridSpec, McOptions, TopologyReport,
    TwoPassOptions,
};
use neus_aug::scene::Normalization;
use std::path::PathBuf;
use std::time::Instant;

/// Marching cubes on an analytic SDF (cross-check hook).
#[derive(Debug, clap::Args)]
pub struct McubesArgs {
    /// Shape: sphere, torus, box or two-spheres (see `mesh::sdf::Shape::named`).
    #[arg(long, default_value = "sphere")]
    pub sdf: String,
    /// Grid points per axis.
    #[arg(long, default_value_t = 64)]
    pub res: usize,
    /// Lower corner of the box, normalised space (`x,y,z`).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "-1,-1,-1"
    )]
    pub min: Vec<f32>,
    /// Upper corner of the box, normalised space (`x,y,z`).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "1,1,1"
    )]
    pub max: Vec<f32>,
    /// Iso level.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub iso: f32,
    /// Coarse pass over the box, then a refined pass over the coarse mesh's padded bounds.
    #[arg(long)]
    pub two_pass: bool,
    /// World units per normalised unit (`scale_mat`'s s); with `--center`, vertices are written in
    /// world coordinates `s·x + c`.
    #[arg(long)]
    pub scale: Option<f64>,
    /// World position of the normalised origin (`scale_mat`'s translation), `x,y,z`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub center: Option<Vec<f64>>,
    /// Output mesh (binary little-endian PLY).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the sampled grid values (single pass only) as a float32 `.npy`.
    #[arg(long)]
    pub grid_out: Option<PathBuf>,
    /// Rayon threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

fn xyz<T: Copy + std::fmt::Debug>(v: &[T], what: &str) -> anyhow::Result<[T; 3]> {
    match v {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => bail!("--{what} takes three comma-separated numbers, got {v:?}"),
    }
}

pub fn run(args: McubesArgs) -> anyhow::Result<()> {
    let work = || -> anyhow::Result<()> { run_inner(&args) };
    match args.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .context("cannot build the thread pool")?
            .install(work),
        None => work(),
    }
}

fn run_inner(args: &McubesArgs) -> anyhow::Result<()> {
    let shape: Shape = args.sdf.parse()?;
    let sdf = move |p: &[[f32; 3]]| shape.eval_batch(p);
    let (min, max) = (xyz(&args.min, "min")?, xyz(&args.max, "max")?);
    let mc = McOptions {
        iso: args.iso,
        ..McOptions::default()
    };
    let grid = GridSpec::cube(min, max, args.res);
    let t = Instant::now();
    let (mut mesh, fine) = if args.two_pass {
        let out = extract_two_pass(
            &sdf,
            &TwoPassOptions {
                min,
                max,
                coarse_res: args.res,
                fine_res: args.res,
                mc,
                ..TwoPassOptions::default()
            },
        )?;
        (out.mesh, out.fine_grid)
    } else {
        (marching_cubes(&sdf, &grid, &mc)?, None)
    };
    let seconds = t.elapsed().as_secs_f64();
    let topo = TopologyReport::of(&mesh);

    if let Some(path) = &args.grid_out {
        if args.two_pass {
            bail!("--grid-out needs a single pass (the two-pass grids differ)");
        }
        let values = sample_grid(&sdf, &grid, &mc)?;
        write_npy(path, &values, [args.res; 3])
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    match (args.scale, &args.center) {
        (Some(scale), Some(c)) => to_world(
            &mut mesh,
            &Normalization {
                scale,
                center: xyz(c, "center")?,
            },
        ),
        (None, None) => {}
        _ => bail!("--scale and --center go together"),
    }
    dtu_eval::ply::write_mesh(&args.out, &mesh)
        .with_context(|| format!("cannot write the mesh {}", args.out.display()))?;
    let json = serde_json::json!({
        "sdf": args.sdf,
        "res": args.res,
        "vertices": mesh.vertices.len(),
        "faces": mesh.faces.len(),
        "boundary_edges": topo.boundary_edges,
        "non_manifold_edges": topo.non_manifold_edges,
        "misoriented_edges": topo.misoriented_edges,
        "euler_characteristic": topo.euler_characteristic,
        "components": topo.components,
        "fine_box": fine.map(|g| [g.min, g.max]),
        "seconds": seconds,
    });
    println!("{json}");
    Ok(())
}

fn write_npy(
    path: &std::path::Path,
    values: &[f32],
    [nx, ny, nz]: [usize; 3],
) -> anyhow::Result<()> {
    use npyz::WriterBuilder;
    use std::io::Write;
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[nz as u64, ny as u64, nx as u64])
        .writer(&mut file)
        .begin_nd()?;
    w.extend(values.iter().copied())?;
    w.finish()?;
    file.flush()?;
    Ok(())
}
