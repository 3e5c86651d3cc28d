//! The configuration tree: one TOML file, parsed with unknown keys refused, then validated.
//!
//! Every field has a documented default, unit and range; every interpretation of the paper
//! (SPEC "(interpretation)") is a field here. Parsing and validation are two steps: serde
//! checks types and names, [`Config::validate`] checks ranges and cross-field rules. Each
//! section is a module holding its fields and their checks.

mod estimator;
mod imu;
mod model_file;
mod net;
mod ppo;
pub mod range;
mod reproduce;
mod robot;
mod run;
mod sim;
mod supervise;
mod task;
mod terrain;
#[cfg(test)]
mod tests;

pub use estimator::{EstimatorConfig, MixtureFeature};
pub use imu::{Accel, FilterConfig, Gyro, ImuConfig, ObservationSource, SensorErrors};
pub use model_file::OfflineMixture;
pub use net::{MIN_KEY_BYTES, NetConfig};
pub use ppo::{PpoConfig, PpoEngine};
pub use reproduce::ReproduceConfig;
pub use robot::{RobotConfig, WheelShape};
pub use run::{Acting, LearnMode, PolicySlot, RunConfig};
pub use sim::{AreaKind, Rect, SimConfig};
pub use supervise::{Restart, RestartPolicy, SuperviseConfig};
pub use task::{EpisodeStart, TaskConfig};
pub use terrain::{HeightmapConfig, TerrainConfig};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A configuration problem, always naming the field or file it is about.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("config field `{field}` = {value}: {reason}")]
    Invalid {
        field: &'static str,
        value: String,
        reason: String,
    },
}

/// The whole configuration of a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct Config {
    pub run: RunConfig,
    pub sim: SimConfig,
    pub ppo: PpoConfig,
    pub estimator: EstimatorConfig,
    pub supervise: SuperviseConfig,
    pub reproduce: ReproduceConfig,
    pub net: NetConfig,
}

impl Config {
    /// Reads, parses and validates a config file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let mut cfg: Self = read_toml(path)?;
        if let Some(dir) = path.parent() {
            // Absolute, so the resolved config the launcher writes into the run directory
            // still names the same files from there.
            let resolve = |p: &mut PathBuf| {
                let joined = dir.join(&*p);
                *p = std::fs::canonicalize(&joined).unwrap_or(joined);
            };
            cfg.run.init_from.iter_mut().for_each(resolve);
            cfg.run.frozen.values_mut().for_each(resolve);
            cfg.estimator.model.iter_mut().for_each(resolve);
            cfg.net.key_file.iter_mut().for_each(resolve);
            cfg.sim
                .terrain
                .heightmap
                .iter_mut()
                .map(|h| &mut h.path)
                .for_each(resolve);
        }
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses TOML text (no validation); `path` only labels errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        parse_toml(text, path)
    }

    /// The config as TOML, for the run directory.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise config: {e}\n"))
    }

    /// Range and cross-field checks. Each section checks its own fields (PPO's minibatch
    /// against the sim's batch); the sections go in a fixed order, `supervise.grace-ms`
    /// after `[reproduce]`, so a config with several mistakes always reports the same one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.run.validate()?;
        self.sim.validate()?;
        self.ppo.validate(self.sim.num_envs())?;
        self.estimator.validate()?;
        self.supervise.validate_restarts()?;
        self.reproduce.validate()?;
        self.supervise.validate_grace()?;
        self.net.validate()
    }

    /// The travel per decision step below which [`EstimatorConfig::min_speed`] deems a
    /// window stationary, metres.
    pub fn min_step_travel(&self) -> f64 {
        self.estimator.min_speed * self.sim.decision_dt()
    }
}

/// Reads and parses a TOML file (no validation), for any file worded like the run config:
/// unknown keys and bad values are [`ConfigError`]s naming the file.
pub fn read_toml<T: DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    parse_toml(&text, path)
}

/// Parses TOML text (no validation); an error is one line naming `path`, line and column.
pub fn parse_toml<T: DeserializeOwned>(text: &str, path: &Path) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| {
        let (line, column) = e.span().map_or((1, 1), |s| line_col(text, s.start));
        ConfigError::Parse {
            path: path.to_path_buf(),
            line,
            column,
            message: e.message().replace('\n', " "),
        }
    })
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, column)
}
