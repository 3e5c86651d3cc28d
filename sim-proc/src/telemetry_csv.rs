//! The telemetry CSV the sim writes (`--telemetry`, alone or in a run): one
//! [`TelemetryRow`] per env and tick; `common::telemetry` reads it back.

use crate::SimError;
use crate::env::{Env, StepInfo};
use crate::task::Ending;
use common::TelemetryRow;
use common::config::{AreaKind, PolicySlot};
use std::path::{Path, PathBuf};

/// One telemetry row for an env after a step: `acted` is the estimate's kind the sim held
/// when it chose the step's action and the policy slot that chose it, when it has them.
pub fn telemetry_row(
    env: &Env,
    info: &StepInfo,
    (estimate, slot): (Option<AreaKind>, Option<PolicySlot>),
) -> TelemetryRow {
    let p = env.pose();
    let imu = env.imu_euler().unwrap_or([f64::NAN; 3]);
    let [l, r] = env.action();
    TelemetryRow {
        env: env.id as u32,
        tick: env.tick - 1,
        area: env.ground(),
        episode: env.episode_index - u64::from(info.ending.is_some()),
        x: p.pos[0],
        y: p.pos[1],
        z: p.pos[2],
        theta_x: p.euler[0],
        theta_y: p.euler[1],
        theta_z: p.euler[2],
        sin_pitch: p.euler[0].sin(),
        action_left: f64::from(l),
        action_right: f64::from(r),
        reward: info.reward,
        terminated: info.ending.is_some_and(super::task::Ending::terminated),
        truncated: info.ending.is_some_and(super::task::Ending::truncated),
        success: info.ending == Some(Ending::Success),
        target_x: info.target[0],
        target_z: info.target[1],
        imu_theta_x: imu[0],
        imu_theta_y: imu[1],
        imu_theta_z: imu[2],
        imu_sin_pitch: imu[0].sin(),
        estimate,
        slot,
    }
}

/// A telemetry CSV (`--telemetry`), one row per env and tick.
pub struct TelemetryCsv {
    path: PathBuf,
    writer: csv::Writer<std::fs::File>,
}

impl TelemetryCsv {
    /// A new file, replacing any earlier one: one standalone run's rows.
    pub fn create(path: &Path) -> Result<Self, SimError> {
        Self::open(path, false)
    }

    /// Appends to the file, with a header only if it is empty: a sim restarted inside a run
    /// keeps the rows of the one before it.
    pub fn append(path: &Path) -> Result<Self, SimError> {
        Self::open(path, true)
    }

    fn open(path: &Path, append: bool) -> Result<Self, SimError> {
        let err = |e: std::io::Error| SimError::Telemetry {
            path: path.to_path_buf(),
            reason: e.to_string(),
        };
        let file = std::fs::OpenOptions::new()
            .create(true)
            .write(true)
            .append(append)
            .truncate(!append)
            .open(path)
            .map_err(err)?;
        let fresh = file.metadata().map_err(err)?.len() == 0;
        Ok(Self {
            path: path.to_path_buf(),
            writer: csv::WriterBuilder::new()
                .has_headers(fresh)
                .from_writer(file),
        })
    }

    fn error(&self, e: &dyn std::fmt::Display) -> SimError {
        SimError::Telemetry {
            path: self.path.clone(),
            reason: e.to_string(),
        }
    }

    pub fn write(&mut self, row: &TelemetryRow) -> anyhow::Result<()> {
        self.writer
            .serialize(row)
            .map_err(|e| self.error(&e).into())
    }

    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.writer.flush().map_err(|e| self.error(&e).into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(env: u32) -> TelemetryRow {
        TelemetryRow {
            env,
            ..Default::default()
        }
    }

    /// Rows of `path` by env, header checked.
    fn envs_in(path: &Path) -> Vec<u32> {
        TelemetryRow::read_csv(path)
            .expect("csv")
            .iter()
            .map(|r| r.env)
            .collect()
    }

    #[test]
    fn a_standalone_run_replaces_the_file_and_a_run_appends_to_it() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("t.csv");
        for (open, env) in [
            (TelemetryCsv::create as fn(&Path) -> _, 1),
            (TelemetryCsv::create, 2),
            (TelemetryCsv::append, 3),
            (TelemetryCsv::append, 4),
        ] {
            let mut csv = open(&path).expect("open");
            csv.write(&row(env)).expect("write");
            csv.flush().expect("flush");
        }
        // The second create dropped the first's row; the appends kept it, under one header.
        assert_eq!(envs_in(&path), vec![2, 3, 4]);
    }
}
