//! `lavatube check-config F`: validate a config without starting anything.

use common::Config;
use std::path::Path;
use std::process::ExitCode;

pub fn check_config(path: &Path) -> anyhow::Result<ExitCode> {
    let cfg = Config::load(path)?;
    println!(
        "{}: ok ({}, {:?} mode, {} steps)",
        path.display(),
        cfg.sim.describe_envs(),
        cfg.run.mode,
        cfg.run.total_steps
    );
    Ok(ExitCode::SUCCESS)
}
