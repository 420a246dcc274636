//! `neus-aug augment`: look at the augmentations before training.
//!
//! - `neus-aug augment INPUT --out DIR`: writes `DIR/contact_sheet.png` (one view under every
//!   manipulation and degradation) and `DIR/contact_sheet.txt` (what each cell is). INPUT is a
//!   PNG or a scene folder (`--view N` picks the view, default 0).
//! - `neus-aug augment --apply KIND:v IN.png OUT.png [--seed N]`: one manipulation (`v = p`) or
//!   degradation (`v = q`, optional) applied to one image, so any image tool can check it.

use anyhow::{bail, Context};
use neus_aug::augment::{contact_sheet, downscale_to_fit, AugmentConfig, ImageOp};
use neus_aug::scene::image::RgbImage;
use neus_aug::scene::{LoadOptions, Scene};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use std::path::{Path, PathBuf};

/// Arguments of `neus-aug augment`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Manipulations (KIND:p): identity, brightness, contrast, saturation, sharpness \
                  (p in [-1, 1], factor 1+p), hue (p in [-0.5, 0.5] turns).\n\
                  Degradations (KIND:q, q optional): gaussian (std, default 0.1), motion-blur \
                  (length px, 5), poisson (photons at white, 10), salt-pepper (probability each, \
                  0.05), speckle (std, 0.4).\n\
                  Examples:\n  neus-aug augment view.png --out sheet/\n  \
                  neus-aug augment --apply hue:0.25 in.png out.png\n  \
                  neus-aug augment --apply gaussian:0.05 --seed 3 in.png out.png"
)]
pub struct AugmentArgs {
    /// Sheet mode: the image (PNG) or scene folder to show. With --apply: IN.png OUT.png.
    #[arg(value_name = "PATHS")]
    paths: Vec<PathBuf>,
    /// Apply one manipulation (KIND:p) or degradation (KIND:q) to IN.png and write OUT.png.
    #[arg(long, value_name = "KIND:V", allow_hyphen_values = true)]
    apply: Option<String>,
    /// Sheet mode: directory for contact_sheet.png and contact_sheet.txt (created if missing).
    #[arg(long, value_name = "DIR", conflicts_with = "apply")]
    out: Option<PathBuf>,
    /// Sheet mode with a scene folder: which view to show.
    #[arg(long, default_value_t = 0)]
    view: usize,
    /// Seed of the random degradations.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Sheet mode: shrink the view (integer box filter) until both sides are at most this many
    /// pixels before applying anything, so the sheet stays small and each effect shows at pixel
    /// scale.
    #[arg(long, value_name = "PX", default_value_t = 320)]
    max_size: usize,
}

pub fn run(args: AugmentArgs) -> anyhow::Result<()> {
    match &args.apply {
        Some(spec) => apply(spec, &args),
        None => sheet(&args),
    }
}

fn apply(spec: &str, args: &AugmentArgs) -> anyhow::Result<()> {
    let op: ImageOp = spec.parse().with_context(|| format!("--apply {spec}"))?;
    let [input, output] = args.paths.as_slice() else {
        bail!(
            "--apply {spec} needs two paths, IN.png OUT.png (got {})",
            args.paths.len()
        );
    };
    if !output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        bail!(
            "--apply {spec}: output {} must be a .png file (augment writes PNG only)",
            output.display()
        );
    }
    let img = RgbImage::load(input)?;
    let mut rng = Pcg64Mcg::seed_from_u64(args.seed);
    op.apply(&img, &mut rng).save(output)?;
    Ok(())
}

fn sheet(args: &AugmentArgs) -> anyhow::Result<()> {
    let [input] = args.paths.as_slice() else {
        bail!(
            "augment takes one INPUT image for the contact sheet (or --apply KIND:v IN OUT); got {} paths",
            args.paths.len()
        );
    };
    let Some(out) = &args.out else {
        bail!(
            "augment {}: --out DIR is required for the contact sheet",
            input.display()
        );
    };
    if args.max_size == 0 {
        bail!("--max-size must be at least 1 pixel");
    }
    let view = load_view(input, args.view, args.max_size)?;
    let view = downscale_to_fit(&view, args.max_size);
    let sheet = contact_sheet(&view, &AugmentConfig::default(), args.seed)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let png = out.join("contact_sheet.png");
    sheet.image.save(&png)?;
    let txt = out.join("contact_sheet.txt");
    dtu_eval::atomic::write_atomic(&txt, sheet.legend().as_bytes())
        .with_context(|| format!("cannot write {}", txt.display()))?;
    println!(
        "wrote {} ({}×{}, {} cells) and {}",
        png.display(),
        sheet.image.width,
        sheet.image.height,
        sheet.cells.len(),
        txt.display()
    );
    Ok(())
}

/// The view to show: a PNG file, or view `view` of a scene folder (DTU layout, loaded with
/// [`Scene::load`], so "view 0" means what it means everywhere else). A scene is decoded already
/// reduced to about `max_size` (a real DTU scene is 49 views of 1600×1200, 1.1 GB as floats).
fn load_view(input: &Path, view: usize, max_size: usize) -> anyhow::Result<RgbImage> {
    if !input.is_dir() {
        if view != 0 {
            bail!(
                "--view {view} needs a scene folder; {} is a file",
                input.display()
            );
        }
        return Ok(RgbImage::load(input)?);
    }
    let downscale = any_png_size(&input.join("image"))
        .map(|(w, h)| (w.max(h) as usize / max_size).max(1))
        .unwrap_or(1);
    let opts = LoadOptions {
        downscale: downscale as u32,
        masks: false,
    };
    let scene = Scene::load(input, &opts)
        .with_context(|| format!("cannot load scene {}", input.display()))?;
    let n = scene.views.len();
    match scene.views.into_iter().nth(view) {
        Some(v) => Ok(v.image),
        None => bail!(
            "--view {view}: scene {} has {n} views (0..={})",
            input.display(),
            n - 1
        ),
    }
}

/// Width and height of some PNG in `dir` (all views of a DTU scene share one size).
fn any_png_size(dir: &Path) -> Option<(u32, u32)> {
    std::fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .and_then(|p| image::image_dimensions(p).ok())
}
