//! `neus-aug import colmap|transforms`: bring posed photographs from COLMAP or instant-ngp /
//! nerfstudio into a NeuS scene folder (see `neus_aug::import`).

use anyhow::{bail, Context};
use neus_aug::import::{self, colmap, transforms, ImportReport, Roi};
use std::path::PathBuf;

/// Import a COLMAP model or a transforms.json into a NeuS scene folder (image/, mask/,
/// cameras_sphere.npz, import.json).
#[derive(Debug, clap::Args)]
pub struct ImportArgs {
    #[command(subcommand)]
    pub source: ImportSource,
}

/// The region of interest override shared by both sources.
#[derive(Debug, clap::Args)]
pub struct RoiArgs {
    /// Centre x,y,z of the region of interest (source world units) that becomes the unit sphere;
    /// with --roi-radius. Default: chosen from the sparse points (COLMAP) or the camera layout
    /// (transforms.json); import.json records the choice.
    #[arg(long, value_parser = import::parse_vec3, requires = "roi_radius", allow_hyphen_values = true)]
    pub roi_center: Option<[f64; 3]>,
    /// Radius of the region of interest (source world units); with --roi-center.
    #[arg(long, requires = "roi_center")]
    pub roi_radius: Option<f64>,
}

impl RoiArgs {
    fn roi(&self) -> anyhow::Result<Option<Roi>> {
        match (self.roi_center, self.roi_radius) {
            (Some(center), Some(radius)) => {
                let roi = Roi { center, radius };
                roi.validate()?;
                Ok(Some(roi))
            }
            (None, None) => Ok(None),
            _ => bail!("--roi-center and --roi-radius go together"),
        }
    }
}

#[derive(Debug, clap::Subcommand)]
pub enum ImportSource {
    /// A COLMAP sparse model (text or binary; e.g. <project>/sparse/0). Cameras must be PINHOLE,
    /// SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL or OPENCV: distorted images (and masks) are
    /// resampled into a pinhole camera with the same K and size. Images may be PNG or JPEG.
    Colmap {
        /// The model folder holding cameras, images and points3D (.txt or .bin).
        sparse: PathBuf,
        /// The folder the model's image names are relative to.
        #[arg(long)]
        images: PathBuf,
        /// Optional mask folder: <name>.png, <stem>.png, or a PNG with the image's number.
        #[arg(long)]
        masks: Option<PathBuf>,
        /// The scene folder to write (absent or empty).
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        roi: RoiArgs,
        /// What the automatic region of interest comes from: `auto` (the default: `cameras` when
        /// the capture orbits the sparse points, with the radius kept near the points, else
        /// `points`), `points` (the sparse points seen by three images or more) or `cameras` (the
        /// point nearest every optical axis, and the largest sphere about it every camera sees
        /// whole: for captures orbiting an object, whose sparse points may cover only the side
        /// the cameras see best). `inspect` and import.json say what was chosen.
        #[arg(long, value_enum, default_value_t = colmap::RoiSource::Auto)]
        roi_from: colmap::RoiSource,
    },
    /// An instant-ngp / nerfstudio transforms.json (OpenGL camera-to-world poses; fl_x/fl_y/cx/cy
    /// or camera_angle_x, shared or per frame). Images may be PNG or JPEG.
    Transforms {
        /// The transforms.json; file paths are relative to its folder.
        json: PathBuf,
        /// The scene folder to write (absent or empty).
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        roi: RoiArgs,
    },
}

fn print_report(r: &ImportReport) {
    let [x, y, z] = r.roi.roi.center;
    println!(
        "wrote {} ({} views{}{}, from {} {}): region of interest centre ({x}, {y}, {z}) radius {} \
         [{}]",
        r.scene.display(),
        r.views,
        if r.masks { ", masks" } else { "" },
        match r.undistorted {
            0 => String::new(),
            n => format!(", {n} undistorted"),
        },
        r.source_format,
        r.source.display(),
        r.roi.roi.radius,
        r.roi.method
    );
}

pub fn run(args: ImportArgs) -> anyhow::Result<()> {
    let report = match args.source {
        ImportSource::Colmap {
            sparse,
            images,
            masks,
            out,
            roi,
            roi_from,
        } => {
            let opts = colmap::ColmapImport {
                model_dir: sparse.clone(),
                images,
                masks,
                roi: roi.roi()?,
                roi_from,
            };
            let (views, choice, format) = colmap::import(&opts)
                .with_context(|| format!("cannot import COLMAP model {}", sparse.display()))?;
            let name = match format {
                colmap::ModelFormat::Text => "colmap-text",
                colmap::ModelFormat::Binary => "colmap-binary",
            };
            import::write_imported_scene(&out, &views, &choice, name, &sparse)
                .with_context(|| format!("cannot write scene {}", out.display()))?
        }
        ImportSource::Transforms { json, out, roi } => {
            let (views, choice) = transforms::import(&json, roi.roi()?)
                .with_context(|| format!("cannot import {}", json.display()))?;
            import::write_imported_scene(&out, &views, &choice, "transforms", &json)
                .with_context(|| format!("cannot write scene {}", out.display()))?
        }
    };
    print_report(&report);
    Ok(())
}
