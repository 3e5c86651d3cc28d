//! The `learner-proc` command line. Exit codes: 0 success, 1 a problem with the input
//! (bad arguments, missing or corrupt checkpoint), 2 anything unexpected.

pub mod export;
pub mod inspect;
pub mod plot;

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// lavatube learner: PPO in burn, checkpoints.
#[derive(Debug, Parser)]
#[command(name = "learner-proc", version)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print a checkpoint's counters and architecture.
    Inspect(inspect::InspectArgs),
    /// Write a checkpoint's actor as a policy file for `sim-proc --controller policy`.
    Export(export::ExportArgs),
    /// Draw a run's learning curves from its metrics CSV into a PNG.
    Plot(plot::PlotArgs),
    /// Join a run over shared memory: train on its rollouts, publish policies, checkpoint.
    Serve(crate::serve::ServeArgs),
}

/// Tunes the allocator, parses `args`, initialises logging (stderr, `RUST_LOG`), runs the
/// command and maps the outcome to an exit code.
pub fn main(args: impl IntoIterator<Item = OsString>) -> ExitCode {
    crate::tune_allocator();
    let cli: Cli = match common::cli::parse(args) {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    common::logging::init();
    match crate::run(&cli.command, &mut std::io::stdout().lock()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("learner-proc: {e}");
            ExitCode::from(if e.is_user_error() { 1 } else { 2 })
        }
    }
}
