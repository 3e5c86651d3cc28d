//! The command line: clap derive, one file per subcommand. Values are checked by clap's
//! parsers before any work starts; the config file is parsed and validated up front.

pub mod analyze;
mod input;
pub mod kinds;
pub mod online;
pub mod serve;

pub use input::{InputArgs, Resolved};

use clap::{Parser, Subcommand};
#[cfg(test)]
use input::parse_window;

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

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Analyze(args) => analyze::execute(&args),
        Command::Kinds(args) => kinds::execute(&args),
        Command::Online(args) => online::execute(&args),
        Command::Serve(args) => serve::execute(&args),
    }
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
