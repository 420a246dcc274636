//! Sub-commands of `neus-aug`. Each lives in its own file; this file only lists them.

use clap::{Parser, Subcommand};

mod inspect;
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
    /// Summarise a scene folder (views, intrinsics, masks, normalisation).
    Inspect(inspect::InspectArgs),
    /// Render a synthetic scene into the DTU layout with its ground truth.
    Synth(synth::SynthArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Inspect(args) => inspect::run(args),
        Command::Synth(args) => synth::run(args),
    }
}
