//! The command line: clap derive, one file per subcommand. Values are checked by clap's
//! parsers before any work starts; the config file is parsed and validated up front.

pub mod analyze;
pub mod kinds;
pub mod online;
pub mod serve;

use clap::{Parser, Subcommand};
use common::config::AttitudeSource;
use std::path::{Path, PathBuf};

/// lavatube terrain estimator: rolling pitch statistics and Gaussian mixtures (SPEC S7).
#[derive(Debug, Parser)]
#[command(name = "estimator-proc", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reproduce the paper's terrain-identification analysis on recorded telemetry:
    /// results.json, results.md (Table 3) and the figures (Figs. 5–8).
    Analyze(analyze::AnalyzeArgs),
    /// Tell several terrain kinds apart offline on recorded telemetry (beyond the paper's
    /// two): a mixture over `estimator.features`, its components named after kinds by the
    /// labels, its confusion and macro accuracy per window, and one ablation per feature.
    Kinds(kinds::KindsArgs),
    /// Replay recorded telemetry through the online estimator: accuracy against window size
    /// and the delay to detect a terrain change.
    Online(online::OnlineArgs),
    /// Join a run over shared memory: classify every env's terrain online and publish it.
    Serve(common::cli::JoinArgs),
}

/// Arguments shared by the subcommands that read a recording.
#[derive(Debug, clap::Args)]
pub struct InputArgs {
    /// Telemetry CSV; its header is the `TelemetryRow` field names (as `sim-proc` writes it).
    pub traces: PathBuf,
    /// Rolling-window sizes in ticks, comma-separated, each 2..=100000 [default: the config's
    /// `estimator.windows`, i.e. 10,20,40,70].
    #[arg(long, value_delimiter = ',', value_parser = parse_window)]
    pub windows: Option<Vec<usize>>,
    /// lavatube TOML config; its `[estimator]` table sets warm-up, components, EM settings
    /// [default: built-in defaults].
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of the k-means++ initialisations [default: the config's `run.seed`].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Whose sin θx to analyse: `truth` (the simulator's pose) or `imu` (the IMU filter's
    /// columns, recorded when the sim ran an IMU) [default: the config's `estimator.signal`].
    #[arg(long, value_parser = parse_signal)]
    pub signal: Option<AttitudeSource>,
}

impl InputArgs {
    /// The validated config with `--windows` applied (sorted, deduplicated), the seed, and
    /// the stationary gate in metres per tick ([`common::Config::min_step_travel`]).
    pub fn resolve(&self) -> anyhow::Result<Resolved> {
        let cfg = load_config(self.config.as_deref())?;
        let min_step_travel = cfg.min_step_travel();
        let mut est = cfg.estimator;
        if let Some(windows) = &self.windows {
            est.windows = windows.clone();
        }
        if let Some(signal) = self.signal {
            est.signal = signal;
        }
        est.windows.sort_unstable();
        est.windows.dedup();
        Ok(Resolved {
            est,
            seed: self.seed.unwrap_or(cfg.run.seed),
            min_step_travel,
            wheels: crate::features::Wheels {
                radius: cfg.sim.robot.wheel_radius,
                dt: cfg.sim.decision_dt(),
            },
        })
    }
}

/// What [`InputArgs::resolve`] settles.
pub struct Resolved {
    pub est: common::config::EstimatorConfig,
    pub seed: u64,
    pub min_step_travel: f64,
    /// The robot's wheels, for the slip feature.
    pub wheels: crate::features::Wheels,
}

fn load_config(path: Option<&Path>) -> anyhow::Result<common::Config> {
    let Some(path) = path else {
        return Ok(common::Config::default());
    };
    Ok(common::Config::load(path).map_err(crate::EstimatorError::from)?)
}

/// `truth` or `imu`.
fn parse_signal(s: &str) -> Result<AttitudeSource, String> {
    match s {
        "truth" => Ok(AttitudeSource::Truth),
        "imu" => Ok(AttitudeSource::Imu),
        _ => Err(format!("`{s}` is not a signal: `truth` or `imu`")),
    }
}

/// A window size: an integer in 2..=100000 (the config's range).
fn parse_window(s: &str) -> Result<usize, String> {
    let w: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a window size (an integer)"))?;
    if (2..=100_000).contains(&w) {
        Ok(w)
    } else {
        Err(format!("window {w} is out of range 2..=100000"))
    }
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Analyze(args) => analyze::execute(&args),
        Command::Kinds(args) => kinds::execute(&args),
        Command::Online(args) => online::execute(&args),
        Command::Serve(args) => serve::execute(&args),
    }
}

/// Writes a report's text to stdout: the CLI's output to its user.
#[allow(
    clippy::print_stdout,
    reason = "the CLI prints its results table to the user"
)]
pub fn print_output(text: &str) {
    println!("{text}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_is_well_formed_and_every_argument_is_documented() {
        common::cli::assert_documented(&Cli::command());
    }

    #[test]
    fn windows_are_checked_before_anything_runs() {
        assert_eq!(parse_window("70"), Ok(70));
        assert!(parse_window("1").is_err());
        assert!(parse_window("x").is_err());
        let cli = Cli::try_parse_from([
            "estimator-proc",
            "analyze",
            "t.csv",
            "--windows",
            "10,70",
            "--out",
            "d",
        ]);
        assert!(cli.is_ok());
        let bad = Cli::try_parse_from([
            "estimator-proc",
            "analyze",
            "t.csv",
            "--windows",
            "10,1",
            "--out",
            "d",
        ]);
        assert!(
            bad.expect_err("rejected")
                .to_string()
                .contains("out of range")
        );
    }
}
