//! Command-line pieces every binary shares: argument parsing with lavatube's exit codes, the
//! run-id value parser, and the arguments with which the launcher starts a process.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

/// Exit code of user errors: bad arguments, config or input files.
pub const EXIT_USER: u8 = 1;

/// Parses `args` as `C`. Usage errors print clap's message and give exit code 1 (a user
/// error); `--help` and `--version` print and give 0.
pub fn parse<C: clap::Parser>(args: impl IntoIterator<Item = OsString>) -> Result<C, ExitCode> {
    C::try_parse_from(args).map_err(|e| {
        let _ = e.print();
        if e.use_stderr() {
            ExitCode::from(EXIT_USER)
        } else {
            ExitCode::SUCCESS
        }
    })
}

/// clap value parser for a run id (see [`crate::ipc::validate_run_id`]).
pub fn parse_run_id(s: &str) -> Result<String, String> {
    crate::ipc::validate_run_id(s).map(|()| s.to_string())
}

/// How the launcher starts a process in a run.
#[derive(Debug, Clone, clap::Args)]
pub struct JoinArgs {
    /// The run's resolved config (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// The run to join over shared memory.
    #[arg(long, value_parser = parse_run_id)]
    pub run_id: String,
}
