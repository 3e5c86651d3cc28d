//! The crate's one error type. Every variant names what it is about (file, line, field, env,
//! window) and prints on one line, so a user sees the cause without a backtrace.

use std::path::PathBuf;

/// What can go wrong in the estimator library.
#[derive(Debug, thiserror::Error)]
pub enum EstimatorError {
    #[error("cannot write {path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error(transparent)]
    Telemetry(#[from] common::telemetry::TelemetryError),
    #[error("{path}: line {line}, column `{field}` is {value}; it must be a finite number")]
    NonFiniteField {
        path: PathBuf,
        line: u64,
        field: &'static str,
        value: f64,
    },
    #[error(
        "{path}: line {line} has no IMU attitude (`imu_sin_pitch` is NaN): it was recorded without an IMU; analyse it with estimator.signal = \"truth\""
    )]
    NoImu { path: PathBuf, line: u64 },
    #[error(
        "{path}: line {line} is on `{kind}` ground; the analysis scores SPEC S7's two kinds, flat and rough (`estimator-proc kinds` scores every kind)"
    )]
    UnscoredKind {
        path: PathBuf,
        line: u64,
        kind: &'static str,
    },
    #[error("{path}: no telemetry rows after the header")]
    Empty { path: PathBuf },
    #[error("value #{index} is {value}; mixture data must be finite")]
    NonFinite { index: usize, value: f64 },
    #[error("env {env}: sin θx = {value}; the online estimator needs a finite value")]
    NonFiniteObservation { env: usize, value: f64 },
    #[error("{n} data point(s) cannot fit {components} mixture components")]
    TooFewPoints { n: usize, components: usize },
    #[error(
        "the data has only {distinct} distinct value(s), fewer than the {components} mixture components (constant data?)"
    )]
    Degenerate { distinct: usize, components: usize },
    #[error("EM failed in all {restarts} restart(s): {reason}")]
    NoFit { restarts: usize, reason: String },
    #[error("invalid mixture: {reason}")]
    InvalidModel { reason: String },
    #[error(
        "window {window}: no series is long enough for one full window after the warm-up (longest: {longest} ticks)"
    )]
    NoWindows { window: usize, longest: usize },
    #[error(
        "the robots stood still in all {stationary} windows of {window} ticks (estimator.min-speed; 0 keeps every window)"
    )]
    AllStationary { window: usize, stationary: usize },
    #[error("window size {window} is out of range: it must be at least 2")]
    BadWindow { window: usize },
    #[error("env {env} is out of range: the estimator tracks {envs} env(s)")]
    EnvOutOfRange { env: usize, envs: usize },
    #[error("the online estimator needs at least one env")]
    NoEnvs,
    #[error(transparent)]
    Config(#[from] common::ConfigError),
    #[error("cannot draw {path}: {reason}")]
    Plot { path: PathBuf, reason: String },
}

impl EstimatorError {
    /// True when the user can fix it (input, config, paths); false for a fault of ours.
    pub fn is_user_error(&self) -> bool {
        !matches!(self, EstimatorError::Plot { .. })
    }
}

/// Shorthand for library results.
pub type Result<T, E = EstimatorError> = std::result::Result<T, E>;
