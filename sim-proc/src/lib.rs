//! lavatube's simulator: the lava-tube floor, the two-wheeled robot and the paper's task in
//! rapier3d (SPEC S1–S5), many envs stepped by a few threads, and controllers that act
//! without a learner. Depends on `common` (never on burn or another process crate).
//!
//! Invariants: a run is bit-for-bit reproducible from its seed whatever the thread count;
//! a non-finite physics state ends that env's episode (truncated) and respawns it, it never
//! stops the process.

pub mod actuator;
pub mod attitude;
pub mod cli;
pub mod controllers;
pub mod driver;
pub mod env;
pub mod external;
pub mod fleet;
pub mod imu;
pub mod outputs;
mod pool;
pub mod randomize;
pub mod robot;
pub mod serve;
pub mod sinkage;
pub mod standalone;
pub mod switching;
pub mod task;
pub mod telemetry_csv;
pub mod terrain;
pub mod track;
mod waiting;
pub mod worlds_csv;

pub use cli::{Args, run};
pub use env::{Env, SharedTerrain, StepInfo};
pub use fleet::Fleet;

use std::path::PathBuf;

/// Errors of the simulator library, each naming what it is about.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Heightmap(#[from] common::terrain::HeightmapError),
    #[error("policy weights {path}: {reason}")]
    Weights { path: PathBuf, reason: String },
    #[error("actions {path}: {reason}")]
    Actions { path: PathBuf, reason: String },
    #[error("telemetry {path}: {reason}")]
    Telemetry { path: PathBuf, reason: String },
    #[error(transparent)]
    Config(#[from] common::ConfigError),
}
