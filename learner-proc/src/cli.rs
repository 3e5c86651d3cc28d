//! The `learner-proc` command line. Exit codes: 0 success, 1 a problem with the input
//! (bad arguments, missing or corrupt checkpoint), 2 anything unexpected.

pub mod export;
pub mod inspect;
pub mod plot;

use std::ffi::OsString;
use std::io::Write;
use std::process::ExitCode;

use crate::LearnerError;
use clap::{Parser, Subcommand};

/// lavatube learner: PPO (a fused engine, burn's autodiff as reference), checkpoints.
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

/// Runs one command of the `learner-proc` binary, writing its report to `out`.
pub fn run(command: &Command, out: &mut dyn Write) -> Result<(), LearnerError> {
    match command {
        Command::Inspect(args) => inspect::inspect(args, out),
        Command::Export(args) => export::export(args, out),
        Command::Plot(args) => plot::plot(args, out),
        Command::Serve(args) => crate::serve::serve(args),
    }
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
    match run(&cli.command, &mut std::io::stdout().lock()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("learner-proc: {e}");
            ExitCode::from(if e.is_user_error() { 1 } else { 2 })
        }
    }
}
