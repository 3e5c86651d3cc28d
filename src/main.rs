//! `lavatube`: starts, supervises and stops the simulator, learner and estimator processes
//! of a run, and manages the shared-memory resources runs leave behind. It links only
//! `common`; the processes are the binaries built beside it.

// The launcher is a terminal program: printing is its job.
#![allow(clippy::print_stdout, clippy::print_stderr)]

mod commands;
mod supervise;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = match commands::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Usage errors are user errors (1); --help and --version are not errors.
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(commands::EXIT_USER)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    match commands::dispatch(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("lavatube: {e:#}");
            ExitCode::from(commands::exit_code(&e))
        }
    }
}
