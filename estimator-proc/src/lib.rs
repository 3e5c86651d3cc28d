//! estimator-proc: the lavatube terrain estimator (SPEC S7, DESIGN §1).
//!
//! Role: turn the robot's pitch into a terrain class. Per env, the rolling std of sin θx over
//! the last `w` ticks ([`rolling`]); a 1-D Gaussian mixture fitted by EM, unsupervised
//! ([`gmm`]); offline, the paper's experiment on recorded telemetry with its table and figures
//! ([`analysis`], [`command::analyze`]); online, a per-env classifier with periodic refits and an
//! optional HMM filter for the runtime ([`online`]), and its replay on recordings
//! ([`evaluation`]). Beyond the paper: several features per window ([`features`]), a
//! d-dimensional mixture ([`mixture`]) whose components are named after terrain kinds on a
//! labelled recording ([`kinds`]), and that named classifier online ([`online_kinds`]).
//!
//! Depends on `common` only among the lavatube crates (no proc crate links another).
//!
//! Invariants:
//! - Rolling stds are sample stds (ddof = 1, pandas' convention) over full windows only; no
//!   window spans two series.
//! - Mixture components are ordered by ascending mean; component 0 is "flat" (SPEC S7).
//! - True area labels are never used to fit, only to score.
//! - Bad input (non-finite values, constant data, too few points, a malformed CSV) is an
//!   [`EstimatorError`] naming its context, never a panic or a NaN result.

pub mod analysis;
pub mod command;
pub mod error;
pub mod evaluation;
pub mod features;
pub mod figures;
pub mod gmm;
pub mod kinds;
pub mod mixture;
pub mod online;
pub mod online_kinds;
pub mod report;
pub mod rolling;
pub mod traces;

pub use command::Cli;
pub use error::{EstimatorError, Result};
pub use gmm::{FitOptions, Gmm};
pub use online::{Estimate, OnlineEstimator};
pub use rolling::{Ddof, RollingStd};

use std::process::ExitCode;

/// Runs the command line (the binary's whole job once arguments are parsed).
pub fn run(cli: Cli) -> anyhow::Result<()> {
    command::run(cli)
}

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
    common::cli::exit(run(cli), EstimatorError::is_user_error)
}
