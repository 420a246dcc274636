//! `neus-aug eval`: the Chamfer evaluation. Same arguments (`dtu_eval::cli::EvalArgs`) and same
//! library function (`dtu_eval::cli::run`) as the `dtu-eval` binary, so the two cannot drift.

use dtu_eval::cli::EvalArgs;

/// Runs the evaluation and prints its labelled summary.
pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    let report = dtu_eval::cli::run(args)?;
    print!("{}", report.summary());
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::cli::{Cli, Command};
    use clap::Parser;

    #[test]
    fn eval_subcommand_parses_the_shared_arguments_and_runs_the_shared_code() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.ply");
        let b = dir.path().join("b.ply");
        let pa = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [5.0, 0.0, 0.0]];
        let pb = [[0.0, 0.5, 0.0], [1.0, 0.0, 2.0]];
        dtu_eval::ply::write_points(&a, &pa, None).unwrap();
        dtu_eval::ply::write_points(&b, &pb, None).unwrap();
        let json = dir.path().join("r.json");
        let cli = Cli::try_parse_from([
            "neus-aug",
            "eval",
            "--mesh",
            a.to_str().unwrap(),
            "--ref",
            b.to_str().unwrap(),
            "--max-dist",
            "3",
            "--json",
            json.to_str().unwrap(),
        ])
        .unwrap();
        let Command::Eval(args) = &cli.command else {
            panic!("not the eval sub-command: {:?}", cli.command)
        };
        assert_eq!(args.max_dist, Some(3.0));
        super::run(args).unwrap();
        let report: dtu_eval::report::Report =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        // a -> b: 0.5, sqrt(1.25), and sqrt(20) ≈ 4.47 left out by the 3 mm cut; b -> a: 0.5, 2.
        let d2s = (0.5 + 1.25f64.sqrt()) / 2.0;
        assert!((report.mean_d2s - d2s).abs() < 1e-12, "{report:?}");
        assert!((report.mean_s2d - 1.25).abs() < 1e-12, "{report:?}");
        assert_eq!(report.chamfer_sum, report.mean_d2s + report.mean_s2d);
        let direct = dtu_eval::cli::run(args).unwrap();
        assert_eq!(
            (direct.mean_d2s, direct.mean_s2d, &direct.details),
            (report.mean_d2s, report.mean_s2d, &report.details)
        );
    }
}
