//! `lavatube run`: one training run (see [`Run`]). Validates the config before anything
//! starts, then runs it to the end and prints its summary.

use crate::runtime::{Run, sweep_dead_runs};
use common::Config;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{SystemTime, UNIX_EPOCH};

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Config file (TOML). Without one: the built-in defaults, documented in
    /// `common/src/config/` (the README's main job is `configs/default.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run id: names the run directory and prefixes every shared-memory resource. Default: a new one.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: Option<String>,
    /// No progress bar (for logs and CI).
    #[arg(long)]
    pub quiet: bool,
}

/// A fresh run id: seconds since the epoch and the launcher's pid, in base 36-ish hex.
fn new_run_id() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!("r{secs:x}-{:x}", std::process::id())
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let cfg = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let run_id = args.run_id.clone().unwrap_or_else(new_run_id);
    Ok(if execute(&cfg, &run_id, &run_id, args.quiet)? {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(130)
    })
}

/// Runs `cfg` in `<run.out-dir>/<dir_name>/` to the end, its processes meeting in the shared
/// memory of run `run_id`, after removing what dead runs left. Returns false when
/// interrupted (Ctrl-C).
pub fn execute(cfg: &Config, dir_name: &str, run_id: &str, quiet: bool) -> anyhow::Result<bool> {
    for (run, files) in sweep_dead_runs() {
        eprintln!("lavatube: removed {files} file(s) left by dead run {run}");
    }
    let finished = Run::prepare(cfg, dir_name, run_id, quiet)?.execute()?;
    Ok(!finished.interrupted)
}
