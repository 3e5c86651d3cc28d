//! What the subcommands that read a recording share: their input arguments, and the
//! config, seed and settings those resolve to.

use common::config::AttitudeSource;
use std::path::{Path, PathBuf};

/// Arguments shared by the subcommands that read a recording.
#[derive(Debug, clap::Args)]
pub struct InputArgs {
    /// Telemetry CSV; its header is the `TelemetryRow` field names (as `sim-proc` writes it).
    pub traces: PathBuf,
    /// Rolling-window sizes in ticks, comma-separated, each 2..=100000 [default: the config's
    /// `estimator.windows`, i.e. 10,20,40,70].
    #[arg(long, value_delimiter = ',', value_parser = parse_window)]
    pub windows: Option<Vec<usize>>,
    /// lavatube TOML config; its `[estimator]` table sets warm-up, components, EM settings
    /// [default: built-in defaults].
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of the k-means++ initialisations [default: the config's `run.seed`].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Whose sin θx to analyse: `truth` (the simulator's pose) or `imu` (the IMU filter's
    /// columns, recorded when the sim ran an IMU) [default: the config's `estimator.signal`].
    #[arg(long, value_parser = parse_signal)]
    pub signal: Option<AttitudeSource>,
}

impl InputArgs {
    /// The validated config with `--windows` applied (sorted, deduplicated), the seed, and
    /// the stationary gate in metres per tick ([`common::Config::min_step_travel`]).
    pub fn resolve(&self) -> anyhow::Result<Resolved> {
        let cfg = load_config(self.config.as_deref())?;
        let min_step_travel = cfg.min_step_travel();
        let mut est = cfg.estimator;
        if let Some(windows) = &self.windows {
            est.windows = windows.clone();
        }
        if let Some(signal) = self.signal {
            est.signal = signal;
        }
        est.windows.sort_unstable();
        est.windows.dedup();
        Ok(Resolved {
            est,
            seed: self.seed.unwrap_or(cfg.run.seed),
            min_step_travel,
            wheels: crate::features::Wheels {
                radius: cfg.sim.robot.wheel_radius,
                dt: cfg.sim.decision_dt(),
            },
        })
    }
}

/// What [`InputArgs::resolve`] settles.
pub struct Resolved {
    pub est: common::config::EstimatorConfig,
    pub seed: u64,
    pub min_step_travel: f64,
    /// The robot's wheels, for the slip feature.
    pub wheels: crate::features::Wheels,
}

/// The config file at `path`, parsed and validated, or the defaults without one.
pub(super) fn load_config(path: Option<&Path>) -> anyhow::Result<common::Config> {
    let Some(path) = path else {
        return Ok(common::Config::default());
    };
    Ok(common::Config::load(path).map_err(crate::EstimatorError::from)?)
}

/// `truth` or `imu`.
fn parse_signal(s: &str) -> Result<AttitudeSource, String> {
    match s {
        "truth" => Ok(AttitudeSource::Truth),
        "imu" => Ok(AttitudeSource::Imu),
        _ => Err(format!("`{s}` is not a signal: `truth` or `imu`")),
    }
}

/// A window size, in the config's range ([`common::config::WINDOW_TICKS`]).
pub(super) fn parse_window(s: &str) -> Result<usize, String> {
    common::cli::parse_count(s, "window size", common::config::WINDOW_TICKS)
}
