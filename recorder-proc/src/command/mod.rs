//! The command line: clap derive, one file per subcommand. Values are checked by clap's
//! parsers before any work starts; the config file is parsed and validated up front.

pub mod convert;
pub mod serve;

use crate::RecorderError;
use clap::{Parser, Subcommand};
use std::path::Path;

/// lavatube recorder: writes a run's telemetry and terrain estimates to a Rerun .rrd file.
#[derive(Debug, Parser)]
#[command(name = "recorder-proc", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Join a run over shared memory and record it until the run stops.
    Serve(serve::ServeArgs),
    /// Convert a telemetry CSV written by the sim into a recording.
    Convert(convert::ConvertArgs),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Serve(args) => serve::execute(&args),
        Command::Convert(args) => convert::execute(&args),
    }
}

fn load_config(path: &Path) -> Result<common::Config, RecorderError> {
    Ok(common::Config::load(path)?)
}

/// Writes a command's result line to stdout: the CLI's output to its user.
#[allow(
    clippy::print_stdout,
    reason = "the CLI prints what it wrote to the user"
)]
fn print_output(text: &str) {
    println!("{text}");
}

/// "<path>: N ticks of robots and M of estimates, X.Y MB".
fn describe(summary: &crate::Summary) -> String {
    format!(
        "{}: {} ticks of robots and {} of estimates logged, {:.1} MB",
        summary.path.display(),
        summary.robot_ticks,
        summary.estimate_ticks,
        summary.bytes as f64 / 1e6
    )
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
    fn serve_takes_the_launchers_arguments_and_an_output() {
        let cli = Cli::try_parse_from([
            "recorder-proc",
            "serve",
            "--config",
            "c.toml",
            "--run-id",
            "demo",
            "--out",
            "run.rrd",
        ])
        .expect("parses");
        let Command::Serve(args) = cli.command else {
            panic!("not serve");
        };
        assert_eq!(args.join.run_id, "demo");
        assert_eq!(args.options, crate::RecordOptions::default());
        let bad = Cli::try_parse_from([
            "recorder-proc",
            "serve",
            "--config",
            "c.toml",
            "--run-id",
            "no_underscores",
            "--out",
            "run.rrd",
        ]);
        assert!(bad.is_err());
        let zero = Cli::try_parse_from([
            "recorder-proc",
            "convert",
            "--config",
            "c.toml",
            "--telemetry",
            "t.csv",
            "--out",
            "run.rrd",
            "--every",
            "0",
        ]);
        assert!(zero.is_err());
    }
}
