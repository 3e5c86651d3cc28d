//! The `lavatube` binary: parses the command line and runs a [`lavatube::commands`] command.

#![allow(clippy::print_stderr)]

use lavatube::commands;
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
