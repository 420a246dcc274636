//! Sub-commands of `neus-aug`. Each lives in its own file; this file only lists them.

use clap::{Parser, Subcommand};

mod augment;
mod eval;
mod export;
mod import;
mod inspect;
mod mcubes;
mod reconstruct;
mod stereo_check;
mod study;
mod synth;

/// NeuS surface reconstruction on the CPU with colour-only image augmentations.
#[derive(Debug, Parser)]
#[command(name = "neus-aug", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Train NeuS on a scene, extract the mesh and score it (default: the embedded scene).
    Reconstruct(Box<reconstruct::ReconstructArgs>),
    /// Chamfer evaluation: DTU protocol (--scan N --gt-root DIR) or two sets (--ref PLY).
    Eval(dtu_eval::cli::EvalArgs),
    /// Export a finished run's mesh with its trained colours: PLY with normals and colours,
    /// textured OBJ and GLB, a turntable; `--check` measures them against the network.
    Export(export::ExportArgs),
    /// Summarise a scene folder (views, intrinsics, masks, normalisation).
    Inspect(inspect::InspectArgs),
    /// Import a COLMAP model or a transforms.json into a NeuS scene folder.
    Import(import::ImportArgs),
    /// Render a synthetic scene into the DTU layout with its ground truth.
    Synth(synth::SynthArgs),
    /// The paper's experiment grids (table2, reduced, degraded, pareto, ...) with seeds,
    /// statistics and plots; `study collect DIR` aggregates a study folder.
    Study(Box<study::StudyArgs>),
    /// Show the augmentations: a contact sheet of one view, or one manipulation/degradation
    /// applied to one image (--apply KIND:v IN.png OUT.png).
    Augment(augment::AugmentArgs),
    /// Marching cubes on an analytic SDF (cross-check hook for scripts/crosscheck_mcubes.py).
    #[command(hide = true)]
    Mcubes(mcubes::McubesArgs),
    /// The depth prior's stereo against a synthetic scene's true mesh (diagnosis hook).
    #[command(hide = true)]
    StereoCheck(stereo_check::StereoCheckArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Reconstruct(args) => reconstruct::run(*args),
        Command::Eval(args) => eval::run(&args),
        Command::Export(args) => export::run(args),
        Command::Inspect(args) => inspect::run(args),
        Command::Import(args) => import::run(args),
        Command::Synth(args) => synth::run(args),
        Command::Study(args) => study::run(*args),
        Command::Augment(args) => augment::run(args),
        Command::Mcubes(args) => mcubes::run(args),
        Command::StereoCheck(args) => stereo_check::run(args),
    }
}
