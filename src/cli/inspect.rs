//! `neus-aug inspect <scene>`: the first command a user runs on new data.

use anyhow::Context;
use neus_aug::scene::{LoadOptions, Scene, SceneSummary};
use std::path::PathBuf;

/// Summarise a scene folder: views, resolution, intrinsics, camera spread, mask coverage, and the
/// normalisation to world millimetres.
#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    /// Scene folder in the NeuS/IDR DTU layout (image/, mask/, cameras_sphere.npz).
    pub scene: PathBuf,
    /// Also write the full summary, with every camera's K and pose, as JSON to this file
    /// (`-` for standard output).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: InspectArgs) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene, &LoadOptions::default())
        .with_context(|| format!("cannot load scene {}", args.scene.display()))?;
    let summary = SceneSummary::of(&scene);
    match args.json.as_deref() {
        Some(p) if p.as_os_str() == "-" => println!("{}", serde_json::to_string_pretty(&summary)?),
        Some(p) => {
            print!("{}", summary.to_text());
            std::fs::write(p, serde_json::to_string_pretty(&summary)?)
                .with_context(|| format!("cannot write {}", p.display()))?;
        }
        None => print!("{}", summary.to_text()),
    }
    Ok(())
}
