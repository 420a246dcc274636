//! Beyond one machine: the study's runs as a job list, a Slurm array script and a GNU parallel
//! command line. No scheduler of our own: each line is a plain shell command run from the study
//! folder, independent of the others, and `neus-aug study collect DIR` reads what they leave.
//!
//! A line is `test -f runs/ID/metrics.json || { …; neus-aug reconstruct … --out runs/ID
//! --resume --quiet; }`: a finished run is skipped, an interrupted one (a preempted array task)
//! resumes from its checkpoint. The program is `$NEUS_AUG` when set, else `neus-aug` from `PATH`.

use super::grid::StudyOptions;
use super::plan::{StudyPlan, BASE_CONFIG_FILE, RUNS_DIR};
use super::{write_atomic, RunSpec, StudyError};
use std::path::{Path, PathBuf};

/// Quotes `s` for a POSIX shell when it needs it.
pub fn shell_quote(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./:=,+@%".contains(c));
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The `reconstruct` arguments of a run, paths relative to the study folder, in the order
/// [`super::plan::overrides`] resolves them.
pub fn reconstruct_args(spec: &RunSpec, opts: &StudyOptions) -> Vec<String> {
    let mut a = vec![
        "reconstruct".to_string(),
        spec.scene.clone(),
        "--preset".into(),
        spec.preset.name().into(),
    ];
    if opts.base_config {
        a.extend(["--config".into(), BASE_CONFIG_FILE.into()]);
    }
    a.extend([
        "--aug".into(),
        spec.arm.name().into(),
        "--seed".into(),
        spec.seed.to_string(),
    ]);
    if let Some(f) = spec.views_fraction {
        a.extend(["--views-fraction".into(), f.to_string()]);
    }
    if let Some(d) = &spec.degrade {
        a.extend(["--degrade".into(), d.clone()]);
    }
    a.extend(["--out".into(), format!("{RUNS_DIR}/{}", spec.id)]);
    for s in opts.sets.iter().chain(&spec.sets) {
        a.extend(["--set".into(), s.clone()]);
    }
    a.extend(["--resume".into(), "--quiet".into()]);
    a
}

/// One line of `jobs.txt` (see the module docs).
pub fn job_line(spec: &RunSpec, opts: &StudyOptions) -> String {
    let out = format!("{RUNS_DIR}/{}", spec.id);
    let cmd: Vec<String> = reconstruct_args(spec, opts)
        .iter()
        .map(|a| shell_quote(a))
        .collect();
    let reuse = spec
        .reuse_training_of
        .as_ref()
        .map(|src| {
            let src = format!("{RUNS_DIR}/{src}");
            format!(
                "if test -f {src}/metrics.json && test ! -f {out}/checkpoint.safetensors; then \
                 mkdir -p {out} && cp {src}/checkpoint.safetensors {out}/; fi; "
            )
        })
        .unwrap_or_default();
    format!(
        "test -f {out}/metrics.json || {{ {reuse}\"${{NEUS_AUG:-neus-aug}}\" {}; }}",
        cmd.join(" ")
    )
}

/// What [`emit`] wrote.
#[derive(Clone, Debug)]
pub struct EmittedJobs {
    pub jobs: PathBuf,
    pub slurm: PathBuf,
    pub parallel: PathBuf,
    pub count: usize,
}

/// Writes `jobs.txt`, `slurm.sbatch`, `parallel.sh` and an empty `logs/` into the study folder.
pub fn emit(dir: &Path, plan: &StudyPlan) -> Result<EmittedJobs, StudyError> {
    let lines: Vec<String> = plan
        .runs
        .iter()
        .map(|r| job_line(r, &plan.options))
        .collect();
    let n = lines.len();
    let grid = plan.options.grid.name();
    let jobs = dir.join("jobs.txt");
    write_atomic(&jobs, format!("{}\n", lines.join("\n")).as_bytes())?;
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).map_err(super::io_err(&logs))?;
    let slurm = dir.join("slurm.sbatch");
    let slurm_text = format!(
        r#"#!/bin/bash
# Slurm array job over jobs.txt ({n} runs of the `{grid}` study), written by
# `neus-aug study {grid} --emit-jobs`. Submit it from the study folder:
#     cd STUDY_DIR && sbatch slurm.sbatch
# Each task runs one line of jobs.txt: finished runs are skipped, preempted ones resume.
# When every task is done:  neus-aug study collect STUDY_DIR
# Adjust the resources to your cluster; a `fast` run needs a few GB and about 15 minutes on
# 2 cores. Set NEUS_AUG to the program's path if `neus-aug` is not on the nodes' PATH.
#SBATCH --job-name=neus-aug-{grid}
#SBATCH --array=1-{n}
#SBATCH --cpus-per-task=4
#SBATCH --mem=8G
#SBATCH --time=04:00:00
#SBATCH --output=logs/%x-%A_%a.out
set -euo pipefail
cd "${{SLURM_SUBMIT_DIR:-.}}"
export RAYON_NUM_THREADS="${{SLURM_CPUS_PER_TASK:-1}}"
line=$(sed -n "${{SLURM_ARRAY_TASK_ID}}p" jobs.txt)
echo "task ${{SLURM_ARRAY_TASK_ID}}: ${{line}}"
exec bash -c "${{line}}"
"#
    );
    write_atomic(&slurm, slurm_text.as_bytes())?;
    let parallel = dir.join("parallel.sh");
    let par_text = format!(
        r#"#!/bin/bash
# Runs the {n} lines of jobs.txt (the `{grid}` study) with GNU parallel, JOBS at a time
# (default 1), from the study folder; finished runs are skipped, interrupted ones resume.
# Usage:  bash parallel.sh [JOBS]        then:  neus-aug study collect STUDY_DIR
set -euo pipefail
cd "$(dirname "$0")"
jobs="${{1:-1}}"
export RAYON_NUM_THREADS="${{RAYON_NUM_THREADS:-$(( $(nproc) / jobs > 0 ? $(nproc) / jobs : 1 ))}}"
parallel --jobs "$jobs" --joblog logs/parallel.joblog --halt never < jobs.txt
"#
    );
    write_atomic(&parallel, par_text.as_bytes())?;
    Ok(EmittedJobs {
        jobs,
        slurm,
        parallel,
        count: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoting() {
        assert_eq!(shell_quote("runs/blob-sia-s0"), "runs/blob-sia-s0");
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote(""), "''");
        assert_eq!(
            shell_quote("model.render.x=[1, 2]"),
            "'model.render.x=[1, 2]'"
        );
    }
}
