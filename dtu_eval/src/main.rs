//! `dtu-eval`: the Chamfer evaluation command line (DTU protocol or plain two-set mode).
//! The same arguments serve `neus-aug eval` (see `dtu_eval::cli`).

use clap::Parser;
use std::process::ExitCode;

/// Chamfer evaluation: DTU protocol (accuracy, completeness, their mean and sum) or plain mode.
#[derive(Debug, Parser)]
#[command(name = "dtu-eval", version, about)]
struct Cli {
    #[command(flatten)]
    args: dtu_eval::cli::EvalArgs,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match dtu_eval::cli::run(&cli.args) {
        Ok(report) => {
            print!("{}", report.summary());
            ExitCode::SUCCESS
        }
        Err(err) => {
            eprintln!("error: {}", dtu_eval::error::error_chain(&err));
            ExitCode::FAILURE
        }
    }
}
