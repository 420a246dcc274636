//! `dtu-eval`: the Chamfer evaluation command line (DTU protocol or plain two-set mode).
//! The same arguments serve `neus-aug eval` (see `dtu_eval::cli`).

use clap::Parser;

/// Chamfer evaluation: DTU protocol (accuracy, completeness, their mean and sum) or plain mode.
#[derive(Debug, Parser)]
#[command(name = "dtu-eval", version, about)]
struct Cli {
    #[command(flatten)]
    args: dtu_eval::cli::EvalArgs,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let report = dtu_eval::cli::run(&cli.args)?;
    print!("{}", report.summary());
    Ok(())
}
