//! Per-update metrics: the run directory's `metrics.csv`, and the same numbers as TensorBoard
//! scalars in an event file beside it.
//!
//! Episode statistics come from the simulator, which alone knows why an episode ended: a
//! positive reward on the last step does not mean success (progress rewards are positive too,
//! SPEC S4), so the runtime passes one [`EpisodeOutcome`] per finished episode.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};

use common::episode::EpisodeStats;
use common::run_dir::METRICS_CSV;
use common::tensorboard::EventWriter;
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

/// TensorBoard tags of the columns ML-Agents also reports, under ML-Agents' names, so its
/// users find them where they look; every other column is `lavatube/<column>`.
const ML_AGENTS_TAGS: [(&str, &str); 5] = [
    ("mean_episode_return", "Environment/Cumulative Reward"),
    ("policy_loss", "Losses/Policy Loss"),
    ("value_loss", "Losses/Value Loss"),
    ("entropy", "Policy/Entropy"),
    ("learning_rate", "Policy/Learning Rate"),
];

impl UpdateMetrics {
    /// Every numeric column with its value (episode columns only when an episode ended).
    fn columns(&self) -> Vec<(&'static str, f64)> {
        let mut c = vec![
            ("update", self.update as f64),
            ("global_step", self.global_step as f64),
            ("policy_version", f64::from(self.policy_version)),
            ("learning_rate", self.learning_rate),
            ("policy_loss", self.policy_loss),
            ("value_loss", self.value_loss),
            ("entropy", self.entropy),
            ("old_approx_kl", self.old_approx_kl),
            ("approx_kl", self.approx_kl),
            ("clip_fraction", self.clip_fraction),
            ("explained_variance", self.explained_variance),
            ("grad_norm", self.grad_norm),
            ("epochs", self.epochs as f64),
            ("samples_per_second", self.samples_per_second),
            ("mean_policy_lag", self.mean_policy_lag),
            ("stale_transitions", self.stale_transitions as f64),
            ("episodes", self.episodes as f64),
        ];
        for (name, v) in [
            ("mean_episode_return", self.mean_episode_return),
            ("success_rate", self.success_rate),
            ("mean_reach_time_s", self.mean_reach_time_s),
        ] {
            c.extend(v.map(|v| (name, v)));
        }
        c
    }

    /// The columns as TensorBoard scalars (see [`ML_AGENTS_TAGS`]).
    pub fn scalars(&self) -> Vec<(String, f64)> {
        self.columns()
            .into_iter()
            .map(|(column, v)| {
                let tag = ML_AGENTS_TAGS
                    .iter()
                    .find(|(c, _)| *c == column)
                    .map_or_else(|| format!("lavatube/{column}"), |(_, t)| (*t).to_string());
                (tag, v)
            })
            .collect()
    }
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
/// file is new, so a resumed learner continues the same file; and each row's
/// [`scalars`](UpdateMetrics::scalars) to a TensorBoard event file in the same directory (a
/// new one per learner process, opened at its first row).
pub struct MetricsLog {
    path: PathBuf,
    writer: csv::Writer<File>,
    events: Option<EventWriter>,
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
        Ok(Self {
            path,
            writer,
            events: None,
        })
    }

    /// Appends one row and flushes it, so a crash loses at most the update in flight; then
    /// its scalars to the event file.
    pub fn append(&mut self, metrics: &UpdateMetrics) -> Result<(), LearnerError> {
        let err = |source| LearnerError::Metrics {
            path: self.path.clone(),
            source,
        };
        self.writer.serialize(metrics).map_err(err)?;
        self.writer.flush().map_err(|e| err(e.into()))?;
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let events = match &mut self.events {
            Some(e) => e,
            None => self.events.insert(
                EventWriter::create(dir)
                    .map_err(LearnerError::io("creating an event file in", dir))?,
            ),
        };
        let scalars = metrics.scalars();
        let values: Vec<(&str, f64)> = scalars.iter().map(|(t, v)| (t.as_str(), *v)).collect();
        let path = events.path().to_path_buf();
        events
            .scalars(metrics.global_step, &values)
            .map_err(LearnerError::io("writing", path))
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
    fn every_numeric_csv_column_is_a_tensorboard_scalar() {
        let mut w = csv::Writer::from_writer(Vec::new());
        let mut m = metrics(3);
        m.mean_episode_return = Some(12.5);
        m.success_rate = Some(0.75);
        m.mean_reach_time_s = Some(6.1);
        w.serialize(&m).expect("row");
        let text = String::from_utf8(w.into_inner().expect("csv")).expect("utf-8");
        let header: Vec<&str> = text.lines().next().expect("header").split(',').collect();
        let scalars = m.scalars();
        let tags: Vec<&str> = scalars.iter().map(|(t, _)| t.as_str()).collect();
        for column in header.iter().filter(|c| **c != "chunks_by_source") {
            let tag = ML_AGENTS_TAGS
                .iter()
                .find(|(c, _)| c == column)
                .map_or_else(|| format!("lavatube/{column}"), |(_, t)| (*t).to_string());
            assert!(tags.contains(&tag.as_str()), "{column} → {tag} missing");
        }
        assert_eq!(tags.len(), header.len() - 1, "{tags:?}");
        let value = |tag: &str| scalars.iter().find(|(t, _)| t == tag).map(|(_, v)| *v);
        assert_eq!(value("Environment/Cumulative Reward"), Some(12.5));
        assert_eq!(value("Losses/Policy Loss"), Some(-0.01));
        assert_eq!(value("lavatube/global_step"), Some(6144.0));
        // No episode ended: no episode scalars (TensorBoard shows a gap, not a zero).
        assert_eq!(metrics(1).scalars().len(), header.len() - 4);
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
        let events = std::fs::read_dir(dir.path())
            .expect("dir")
            .filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().contains("tfevents"))
            })
            .count();
        assert_eq!(
            events, 2,
            "an event file per learner process, beside metrics.csv"
        );
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
