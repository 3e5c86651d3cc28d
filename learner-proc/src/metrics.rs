//! Per-update metrics and the run directory's `metrics.csv`.
//!
//! Episode statistics come from the simulator, which alone knows why an episode ended: a
//! positive reward on the last step does not mean success (progress rewards are positive too,
//! SPEC S4), so the runtime passes one [`EpisodeOutcome`] per finished episode.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};

use common::episode::EpisodeStats;
use common::run_dir::METRICS_CSV;
use serde::{Deserialize, Serialize};

use crate::LearnerError;

/// How one episode ended, reported by the simulator alongside the rollout.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeOutcome {
    pub env: u32,
    /// Undiscounted sum of the episode's rewards.
    pub episode_return: f32,
    /// Decision steps the episode lasted.
    pub steps: u32,
    /// The target was reached (SPEC S3), as opposed to a time-out, distance or fault failure.
    pub success: bool,
}

/// What one update did, one CSV row. Losses, KL, clip fraction and gradient norm are means over
/// the update's minibatches; episode columns are empty when no episode ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UpdateMetrics {
    pub update: u64,
    pub global_step: u64,
    pub policy_version: u32,
    pub learning_rate: f64,
    pub policy_loss: f64,
    pub value_loss: f64,
    pub entropy: f64,
    pub old_approx_kl: f64,
    pub approx_kl: f64,
    pub clip_fraction: f64,
    pub explained_variance: f64,
    /// Global gradient norm before clipping.
    pub grad_norm: f64,
    /// Epochs run (fewer than configured when `target-kl` stopped the update).
    pub epochs: usize,
    /// Minibatch samples × epochs per second of wall time for the whole update.
    pub samples_per_second: f64,
    /// Mean of (current version − the version that acted) over the rollout; 0 in sync mode.
    pub mean_policy_lag: f64,
    /// Transitions not trained on because they were more than `max-policy-lag` versions old.
    pub stale_transitions: usize,
    pub episodes: usize,
    pub mean_episode_return: Option<f64>,
    pub success_rate: Option<f64>,
    /// Mean duration of the successful episodes, seconds.
    pub mean_reach_time_s: Option<f64>,
    /// Rollout chunks received so far from each sim, `source:chunks` separated by spaces:
    /// `0:12` on one host, `1:8 2:8` with two sim hosts (DESIGN §9).
    pub chunks_by_source: String,
}

/// Episode columns of a metrics row.
pub(crate) struct EpisodeSummary {
    pub count: usize,
    pub mean_return: Option<f64>,
    pub success_rate: Option<f64>,
    pub mean_reach_time_s: Option<f64>,
}

impl EpisodeSummary {
    /// Success rate and reach time by [`EpisodeStats`]'s formulas, the ones every other
    /// reader of episode outcomes uses; all columns empty when no episode ended.
    pub fn of(episodes: &[EpisodeOutcome], decision_dt: f64) -> Self {
        let mut stats = EpisodeStats::default();
        for e in episodes {
            stats.record(e.success, u64::from(e.steps));
        }
        let count = episodes.len();
        let ended = count > 0;
        let total_return = episodes
            .iter()
            .fold(0.0, |sum, e| sum + f64::from(e.episode_return));
        Self {
            count,
            mean_return: ended.then(|| total_return / count as f64),
            success_rate: ended.then(|| stats.success_rate()),
            mean_reach_time_s: stats.reach_seconds(decision_dt).map(|(mean, _)| mean),
        }
    }
}

/// Appends [`UpdateMetrics`] rows to `<run-dir>/metrics.csv`, writing the header only when the
/// file is new, so a resumed learner continues the same file.
pub struct MetricsLog {
    path: PathBuf,
    writer: csv::Writer<File>,
}

impl MetricsLog {
    pub fn open(run_dir: &Path) -> Result<Self, LearnerError> {
        let path = run_dir.join(METRICS_CSV);
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(LearnerError::io("opening", &path))?;
        let is_new = file
            .metadata()
            .map_err(LearnerError::io("reading metadata of", &path))?
            .len()
            == 0;
        let writer = csv::WriterBuilder::new()
            .has_headers(is_new)
            .from_writer(file);
        Ok(Self { path, writer })
    }

    /// Appends one row and flushes it, so a crash loses at most the update in flight.
    pub fn append(&mut self, metrics: &UpdateMetrics) -> Result<(), LearnerError> {
        let err = |source| LearnerError::Metrics {
            path: self.path.clone(),
            source,
        };
        self.writer.serialize(metrics).map_err(err)?;
        self.writer.flush().map_err(|e| err(e.into()))
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(update: u64) -> UpdateMetrics {
        UpdateMetrics {
            update,
            global_step: 2048 * update,
            policy_version: update as u32,
            learning_rate: 3e-4,
            policy_loss: -0.01,
            value_loss: 0.5,
            entropy: 2.8,
            old_approx_kl: 0.001,
            approx_kl: 0.002,
            clip_fraction: 0.1,
            explained_variance: 0.3,
            grad_norm: 0.7,
            epochs: 10,
            samples_per_second: 1e5,
            mean_policy_lag: 0.0,
            stale_transitions: 0,
            episodes: 0,
            mean_episode_return: None,
            success_rate: None,
            mean_reach_time_s: None,
            chunks_by_source: "1:8 2:7".into(),
        }
    }

    #[test]
    fn episode_summary_counts_successes_and_their_times() {
        let e = |episode_return, steps, success| EpisodeOutcome {
            env: 0,
            episode_return,
            steps,
            success,
        };
        let s = EpisodeSummary::of(
            &[e(10.0, 50, true), e(-2.0, 300, false), e(4.0, 70, true)],
            0.1,
        );
        assert_eq!(s.count, 3);
        assert!((s.mean_return.expect("episodes") - 4.0).abs() < 1e-12);
        assert!((s.success_rate.expect("episodes") - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.mean_reach_time_s.expect("successes") - 6.0).abs() < 1e-9);
        let none = EpisodeSummary::of(&[], 0.1);
        assert_eq!(
            (none.count, none.mean_return, none.mean_reach_time_s),
            (0, None, None)
        );
    }

    #[test]
    fn csv_header_once_across_reopen() {
        let dir = tempfile::tempdir().expect("tempdir");
        MetricsLog::open(dir.path())
            .expect("open")
            .append(&metrics(1))
            .expect("append");
        let mut log = MetricsLog::open(dir.path()).expect("reopen");
        log.append(&metrics(2)).expect("append");
        let text = std::fs::read_to_string(log.path()).expect("read");
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        assert!(
            lines[0].starts_with("update,global_step,policy_version,learning_rate,policy_loss")
        );
        assert!(lines[1].starts_with("1,2048,1,"));
        assert!(
            lines[2].starts_with("2,4096,2,") && lines[2].ends_with(",0,0,,,,1:8 2:7"),
            "{}",
            lines[2]
        );
    }
}
