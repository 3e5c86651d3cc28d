//! `lavatube analyze`: the paper's terrain analysis (SPEC S7) on recorded telemetry, run by
//! the estimator's binary (the launcher links no process crate).

use crate::runtime;
use anyhow::Context;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct AnalyzeArgs {
    /// Passed to `estimator-proc analyze`: TRACES.csv [--windows 10,20,40,70] --out DIR
    /// [--config F] [--seed N] (see `estimator-proc analyze --help`).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, required = true)]
    pub args: Vec<String>,
}

pub fn analyze(args: AnalyzeArgs) -> anyhow::Result<ExitCode> {
    let bin = runtime::locate("estimator-proc")?;
    let status = std::process::Command::new(&bin)
        .arg("analyze")
        .args(&args.args)
        .status()
        .with_context(|| format!("cannot start {}", bin.display()))?;
    Ok(ExitCode::from(
        status.code().map_or(super::EXIT_FAILURE, |c| c as u8),
    ))
}
