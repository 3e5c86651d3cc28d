//! `lavatube`: starts, supervises and stops the simulator, learner and estimator processes
//! of a run, and manages the shared-memory resources runs leave behind. It links only
//! `common`; the processes are the binaries built beside it.

// The launcher is a terminal program: printing is its job.
#![allow(clippy::print_stdout, clippy::print_stderr)]

mod commands;
mod supervise;

use std::process::ExitCode;

fn main() -> ExitCode {
    let cli: commands::Cli = match common::cli::parse(std::env::args_os()) {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    match commands::dispatch(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("lavatube: {e:#}");
            ExitCode::from(commands::exit_code(&e))
        }
    }
}
