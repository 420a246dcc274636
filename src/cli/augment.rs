//! `neus-aug augment`: look at the augmentations before training.
//!
//! - `neus-aug augment INPUT --out DIR`: writes `DIR/contact_sheet.png` (one view under every
//!   manipulation and degradation) and `DIR/contact_sheet.txt` (what each cell is).
//! - `neus-aug augment --apply KIND:v IN.png OUT.png [--seed N]`: one manipulation (`v = p`) or
//!   degradation (`v = q`, optional) applied to one image, so any image tool can check it.

use anyhow::{bail, Context};
use neus_aug::augment::{contact_sheet, downscale_to_fit, AugmentConfig, ImageOp};
use neus_aug::scene::image::RgbImage;
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
    /// Sheet mode: the image (PNG) to show. With --apply: IN.png OUT.png.
    #[arg(value_name = "PATHS")]
    paths: Vec<PathBuf>,
    /// Apply one manipulation (KIND:p) or degradation (KIND:q) to IN.png and write OUT.png.
    #[arg(long, value_name = "KIND:V", allow_hyphen_values = true)]
    apply: Option<String>,
    /// Sheet mode: directory for contact_sheet.png and contact_sheet.txt (created if missing).
    #[arg(long, value_name = "DIR", conflicts_with = "apply")]
    out: Option<PathBuf>,
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
    let view = load_view(input)?;
    let view = downscale_to_fit(&view, args.max_size);
    let sheet = contact_sheet(&view, &AugmentConfig::default(), args.seed)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let png = out.join("contact_sheet.png");
    sheet.image.save(&png)?;
    let txt = out.join("contact_sheet.txt");
    std::fs::write(&txt, sheet.legend())
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

/// The view to show: a PNG file. (A scene folder will be accepted once the scene loader lands;
/// until then a folder is a clear error pointing at its images.)
fn load_view(input: &Path) -> anyhow::Result<RgbImage> {
    if input.is_dir() {
        bail!(
            "{} is a directory: pass one of its images (e.g. {}) until scene folders are supported",
            input.display(),
            input.join("image/000000.png").display()
        );
    }
    Ok(RgbImage::load(input)?)
}
