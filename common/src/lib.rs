//! The lavatube contract shared by every process: the configuration tree, the policy
//! network's flat weight layout with a plain-Rust forward pass, rollout transitions,
//! telemetry rows and a checkpointable RNG.
//!
//! Depends on neither rapier nor burn, so every process can link it cheaply.

#[cfg(feature = "plot")]
pub mod bars;
pub mod cli;
pub mod clock;
pub mod config;
pub mod coverage;
pub mod episode;
pub mod ipc;
pub mod logging;
#[cfg(feature = "plot")]
pub mod map;
pub mod obj;
pub mod observation;
#[cfg(feature = "plot")]
pub mod plot;
pub mod policy;
pub mod refusals;
pub mod rng;
pub mod rollout;
pub mod run_dir;
pub mod telemetry;
pub mod tensorboard;
pub mod terrain;
pub mod track;
pub mod wire;

pub use config::{AreaKind, Config, ConfigError};
pub use policy::{Policy, PolicyLayout};
pub use rng::Rng;
pub use rollout::Transition;
pub use telemetry::TelemetryRow;

/// Observation size (SPEC S5).
pub const OBS_DIM: usize = 10;
/// Action size: left and right wheel commands (SPEC S2).
pub const ACT_DIM: usize = 2;
