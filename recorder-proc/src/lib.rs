//! recorder-proc: a Rerun recording (`.rrd`) of a lavatube run.
//!
//! Role: a reader of the run's `telemetry` and `terrain` services, like the estimator, that
//! writes what it reads to a file any Rerun viewer opens: the floor as a mesh, every robot's
//! pose and recent trail, and per-env time series of the pitch signal, the estimator's
//! view and the reward, on a `tick` sequence timeline ([`recording`]). `serve` records a live
//! run; `convert` turns a telemetry CSV written by the sim into the same recording afterwards.
//!
//! This is the only lavatube crate that links `rerun`; it depends on `common` alone among
//! the lavatube crates.
//!
//! Invariants:
//! - A recording never stops a run: `serve` ends on the run's stop request, and any error of
//!   its own ends only this process (the launcher treats its exit as non-fatal).
//! - On every exit path that returns, the file is flushed and closed, so it is readable.
//! - Only every `every`-th tick is logged (the first tick seen in each block of `every`), so
//!   a file's size is bounded by the run's length over `every`, not by the sim's speed.

pub mod command;
pub mod decimate;
pub mod entity;
pub mod error;
pub mod mesh;
pub mod options;
pub mod pose;
pub mod recording;
pub mod sample;
pub mod trail;

pub use command::Cli;
pub use error::{RecorderError, Result};
pub use options::RecordOptions;
pub use recording::{Recording, Summary};

use std::process::ExitCode;

/// Parses `args`, runs, prints any error on one line and maps it to the exit code:
/// 0 ok, 1 a user, config or input error, 2 anything unexpected.
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli: Cli = match common::cli::parse(args.into_iter().map(Into::into)) {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    common::logging::init();
    common::cli::exit(command::run(cli), RecorderError::is_user_error)
}
