//! Sub-commands of `neus-aug`. Each lives in its own file; this file only lists them.

mod eval;

use clap::{Parser, Subcommand};

/// NeuS surface reconstruction on the CPU with colour-only image augmentations.
#[derive(Debug, Parser)]
#[command(name = "neus-aug", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Summarise a scene folder (views, intrinsics, masks, normalisation).
    Inspect { scene: std::path::PathBuf },
    /// Chamfer evaluation: DTU protocol (--scan N --gt-root DIR) or two sets (--ref PLY).
    Eval(dtu_eval::cli::EvalArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Inspect { scene } => anyhow::bail!(
            "inspect {}: scene loading lands with the foundation issue",
            scene.display()
        ),
        Command::Eval(args) => eval::run(&args),
    }
}
