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
    if args.json.as_deref().is_none_or(|p| p.as_os_str() != "-") {
        print_import_record(&args.scene.join("import.json"));
    }
    Ok(())
}

/// What `neus-aug import` chose, from the scene's `import.json` (absent for other scenes).
fn print_import_record(path: &std::path::Path) {
    let Ok(text) = std::fs::read_to_string(path) else {
        return;
    };
    let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) else {
        println!("imported     ({} does not parse)", path.display());
        return;
    };
    println!(
        "imported     from {} {}",
        v["source_format"].as_str().unwrap_or("?"),
        v["source"].as_str().unwrap_or("?")
    );
    println!(
        "region       centre {} radius {} (source units): {}",
        v["roi"]["roi"]["center"],
        v["roi"]["roi"]["radius"],
        v["roi"]["method"].as_str().unwrap_or("?")
    );
    if let Some(n) = v["undistorted"].as_u64().filter(|&n| n > 0) {
        println!("undistorted  {n} views (lens distortion resampled into pinhole images)");
    }
}
