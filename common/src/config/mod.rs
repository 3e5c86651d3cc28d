//! The configuration tree: one TOML file, parsed with unknown keys refused, then validated.
//!
//! Every field is declared once ([`setting::settings!`]) with its default, range or choices,
//! unit, tier and doc; every interpretation of the paper (SPEC "(interpretation)") is a field
//! here. Parsing and validation are two steps: serde checks types and names,
//! [`Config::validate`] checks ranges and cross-field rules. Each section is a module holding
//! its fields and the rules between them; [`reference`] makes docs/CONFIG.md from them.

mod estimator;
mod external;
mod imu;
mod kinds;
mod model_file;
mod net;
mod ppo;
mod randomize;
pub mod range;
pub mod reference;
mod reproduce;
mod robot;
mod run;
pub mod setting;
mod sim;
mod supervise;
mod task;
mod terrain;
#[cfg(test)]
mod tests;

pub use estimator::{
    Covariance, EstimatorConfig, KindsFit, MixtureFeature, OnPlacement, WINDOW_TICKS, WindowFeature,
};
pub use external::ExternalConfig;
pub use imu::{Accel, AttitudeSource, FilterConfig, Gyro, ImuConfig, SensorErrors};
pub use kinds::{Acting, AreaKind, PolicySlot};
pub use model_file::{OfflineKinds, OfflineMixture};
pub use net::{MIN_KEY_BYTES, NetConfig};
pub use ppo::{PpoConfig, PpoEngine};
pub use randomize::RandomizeConfig;
pub use reproduce::ReproduceConfig;
pub use robot::{RobotConfig, WheelModel, WheelShape};
pub use run::{LearnMode, RunConfig};
pub use sim::{Rect, SimConfig};
pub use supervise::{Restart, RestartPolicy, SuperviseConfig};
pub use task::{EpisodeStart, TaskConfig};
pub use terrain::{
    Area, GravelConfig, HeightmapConfig, SandConfig, SlopeConfig, TerrainCollider, TerrainConfig,
};

use serde::de::DeserializeOwned;
use setting::Setting;
use std::collections::HashSet;
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
        field: String,
        value: String,
        reason: String,
    },
}

setting::settings! {
    /// The whole configuration of a run.
    pub struct Config {
        pub run: RunConfig = RunConfig::default();
        pub sim: SimConfig = SimConfig::default();
        pub ppo: PpoConfig = PpoConfig::default();
        pub estimator: EstimatorConfig = EstimatorConfig::default();
        pub supervise: SuperviseConfig = SuperviseConfig::default();
        pub reproduce: ReproduceConfig = ReproduceConfig::default();
        pub net: NetConfig = NetConfig::default();
    }
}

impl Config {
    /// Reads, parses and validates a config file. A top-level `extends = "FILE"` starts from
    /// that config (relative to this file) and overrides only the keys this file sets.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = read_text(path)?;
        let table: toml::Table = parse_toml(&text, path)?;
        refuse_replaced_keys(&table)?;
        let mut cfg: Self = if table.contains_key(EXTENDS) {
            from_merged(extended(table, path, 0)?, path)?
        } else {
            parse_toml(&text, path)?
        };
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
            cfg.estimator.kinds_model.iter_mut().for_each(resolve);
            cfg.net.key_file.iter_mut().for_each(resolve);
            cfg.reproduce.robustness_worlds.iter_mut().for_each(resolve);
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
        refuse_replaced_keys(&parse_toml(text, path)?)?;
        parse_toml(text, path)
    }

    /// This config with `top` laid over it as a config that `extends` it would be (a section
    /// merges key by key, a field replaces), then checked; `path` labels errors.
    pub fn overlaid(&self, top: toml::Table, path: &Path) -> Result<Self, ConfigError> {
        refuse_replaced_keys(&top)?;
        let mut base = toml::Table::try_from(self).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            line: 1,
            column: 1,
            message: e.to_string().replace('\n', " "),
        })?;
        lay_over(&mut base, top);
        let cfg = from_merged(base, path)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// The config as TOML, for the run directory.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise config: {e}\n"))
    }

    /// Range and cross-field checks: first every field against its declared range, in
    /// declaration order, then each section's rules between fields (PPO's minibatch against
    /// the sim's batch) in a fixed order, so a config with several mistakes always reports
    /// the same one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        Setting::check(self, "", &setting::form("the whole config"))?;
        self.run.validate(self.sim.acting)?;
        self.sim.validate()?;
        self.ppo.validate(self.sim.num_envs())?;
        self.estimator.validate()?;
        if self.estimator.signal == AttitudeSource::Imu && !self.sim.simulates_imu() {
            return Err(range::invalid(
                "estimator.signal",
                "imu",
                "needs the IMU simulated: set sim.observation = \"imu\" or sim.imu.simulate = true",
            ));
        }
        self.reproduce
            .validate(&self.sim.terrain.kinds(), &self.estimator.windows)
    }

    /// The travel per decision step below which [`EstimatorConfig::min_speed`] deems a
    /// window stationary, metres.
    pub fn min_step_travel(&self) -> f64 {
        self.estimator.min_speed * self.sim.decision_dt()
    }
}

/// Keys an older release read that a table replaced: `sim.flat-envs = 4` and its kin are
/// refused with the line that replaces them (`envs = { flat = 4, … }` under `[sim]`).
fn refuse_replaced_keys(table: &toml::Table) -> Result<(), ConfigError> {
    let Some(toml::Value::Table(sim)) = table.get("sim") else {
        return Ok(());
    };
    let old: Vec<(&str, &toml::Value)> = sim
        .iter()
        .filter_map(|(key, n)| {
            let area = key.strip_suffix("-envs")?;
            AreaKind::ALL
                .iter()
                .any(|a| a.name() == area)
                .then_some((area, n))
        })
        .collect();
    let Some((first, n)) = old.first() else {
        return Ok(());
    };
    let table: Vec<String> = old
        .iter()
        .map(|(area, n)| format!("{area} = {n}"))
        .collect();
    Err(ConfigError::Invalid {
        field: format!("sim.{first}-envs"),
        value: n.to_string(),
        reason: format!(
            "env counts are one table: write `envs = {{ {} }}` under [sim]",
            table.join(", ")
        ),
    })
}

/// The top-level key naming the config a config file starts from.
const EXTENDS: &str = "extends";

/// How deep `extends` may chain (a cycle ends here).
const MAX_EXTENDS: usize = 8;

/// `table`, the file at `path`, laid over the config its `extends` names (relative to
/// `path`), recursively: tables merge key by key, any other value replaces the base's.
fn extended(mut table: toml::Table, path: &Path, depth: usize) -> Result<toml::Table, ConfigError> {
    let Some(base) = table.remove(EXTENDS) else {
        return Ok(table);
    };
    let invalid = |reason: &str| ConfigError::Invalid {
        field: EXTENDS.to_owned(),
        value: base.to_string(),
        reason: format!("{reason} (in {})", path.display()),
    };
    let Some(name) = base.as_str() else {
        return Err(invalid("must be the path of a config file"));
    };
    if depth >= MAX_EXTENDS {
        return Err(invalid("chains more than 8 files deep (a cycle?)"));
    }
    let base_path = path.parent().unwrap_or(Path::new("")).join(name);
    let text = read_text(&base_path)?;
    let base_table = parse_toml(&text, &base_path)?;
    refuse_replaced_keys(&base_table)?;
    let mut merged = extended(base_table, &base_path, depth + 1)?;
    lay_over(&mut merged, table);
    Ok(merged)
}

/// Lays the config table `top` over the config table `base` ([`overlay`], knowing which
/// keys are fields).
fn lay_over(base: &mut toml::Table, top: toml::Table) {
    let fields: HashSet<String> = reference::rows().into_iter().map(|r| r.key).collect();
    overlay(base, top, "", &fields);
}

/// The config a merged table holds (unvalidated); its errors name `path`, the file the
/// table was laid over from, without a line (a merge has none).
fn from_merged(table: toml::Table, path: &Path) -> Result<Config, ConfigError> {
    toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            path: path.to_path_buf(),
            line: 1,
            column: 1,
            message: e.message().replace('\n', " "),
        })
}

/// Lays `top` over `base`: a section merges key by key; a field, a table-valued one
/// (`sim.envs`, `run.frozen`) included, replaces the base's value.
fn overlay(base: &mut toml::Table, top: toml::Table, prefix: &str, fields: &HashSet<String>) {
    for (key, value) in top {
        let path = setting::key(prefix, &key);
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) if !fields.contains(&path) => {
                overlay(b, t, &path, fields);
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

fn read_text(path: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Reads and parses a TOML file (no validation), for any file worded like the run config:
/// unknown keys and bad values are [`ConfigError`]s naming the file.
pub fn read_toml<T: DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    parse_toml(&read_text(path)?, path)
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
