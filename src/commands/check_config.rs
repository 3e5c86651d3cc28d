//! `lavatube check-config F`: validate a config without starting anything. A file with a
//! `[bench]` table is a bench file (`lavatube bench --config F`) and is checked as one,
//! with the runtime config it names. `--explain FIELD` prints a field's doc, default and
//! accepted values; `--reference` the page of every field (docs/CONFIG.md).

use super::UserError;
use super::bench::Plan;
use common::Config;
use common::config::{ConfigError, reference};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["config", "explain", "reference"])))]
pub struct CheckArgs {
    /// The config file (TOML).
    config: Option<PathBuf>,
    /// Print this field's doc, default, accepted values, unit and tier (`ppo.clip-coef`),
    /// or every field of a section (`ppo`).
    #[arg(long, value_name = "FIELD")]
    explain: Option<String>,
    /// Print the reference of every field as Markdown (docs/CONFIG.md).
    #[arg(long)]
    reference: bool,
}

/// Does the one thing asked (the argument group takes exactly one of the three).
pub fn check_config(args: &CheckArgs) -> anyhow::Result<ExitCode> {
    if let Some(path) = &args.config {
        println!("{}: ok ({})", path.display(), validate(path)?);
    } else if let Some(key) = &args.explain {
        print!("{}", reference::explain(key).map_err(UserError)?);
    } else {
        print!("{}", reference::markdown());
    }
    Ok(ExitCode::SUCCESS)
}

/// Loads and validates `path` as a run config or a bench file; what it describes.
fn validate(path: &Path) -> anyhow::Result<String> {
    if is_bench_file(path)? {
        let plan = Plan::load(Some(path), false)?;
        return Ok(format!(
            "bench: {} measurements, envs {:?}, threads {:?}",
            plan.measurements().len(),
            plan.bench.envs,
            plan.bench.threads
        ));
    }
    let cfg = Config::load(path)?;
    Ok(format!(
        "{}, {:?} mode, {} steps",
        cfg.sim.describe_envs(),
        cfg.run.mode,
        cfg.run.total_steps
    ))
}

/// Whether the file's TOML has a top-level `bench` table. A file that is no TOML at all is
/// left to [`Config::load`], whose error names the line.
fn is_bench_file(path: &Path) -> Result<bool, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    Ok(text
        .parse::<toml::Table>()
        .is_ok_and(|t| t.get("bench").is_some_and(toml::Value::is_table)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_config_loads_and_validates() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .expect("configs/")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        assert!(files.len() >= 5, "{files:?}");
        for f in &files {
            let said = validate(f).unwrap_or_else(|e| panic!("{}: {e:#}", f.display()));
            assert!(!said.is_empty());
        }
        let bench = validate(&dir.join("bench.toml")).expect("bench.toml");
        assert!(bench.starts_with("bench: "), "{bench}");
    }

    #[test]
    fn a_run_config_with_a_bench_table_is_a_bench_file_and_its_errors_say_so() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let f = tmp.path().join("b.toml");
        std::fs::write(&f, "[bench]\nrepeats = 0\n").expect("write");
        let e = validate(&f).expect_err("repeats 0");
        assert!(e.to_string().contains("bench.repeats"), "{e}");
    }
}
