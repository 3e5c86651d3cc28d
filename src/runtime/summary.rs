//! What a run reports: the progress it shows while it runs, read from its own telemetry and
//! terrain services, and the typed [`Summary`] behind `summary.json` when it ends.

use super::numbers::thousands;
use common::config::PolicySlot;
use common::episode::EpisodeStats;
use common::wire::{TerrainHeader, TickHeader};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What the run's telemetry, terrain and policy services said last.
#[derive(Debug, Default, Clone)]
pub struct Progress {
    pub tick: TickHeader,
    pub terrain: TerrainHeader,
    /// Envs see flat and rough ground (both areas, or the mixed course): only then does
    /// scoring a two-class terrain estimate mean anything.
    pub both_areas: bool,
    /// Per policy slot, the learners' failed checkpoint and metrics writes.
    pub write_failures: BTreeMap<PolicySlot, WriteFailures>,
    /// The most env steps a learner's policy has learned from, over every sim it hears, and
    /// the newest policy version.
    pub learned_steps: u64,
    pub learned_version: u32,
}

/// One slot's failed writes, summed over the learner processes that served it (each counts
/// its own from 0).
#[derive(Debug, Default, Clone, Copy)]
pub struct WriteFailures {
    learner: u32,
    current: u32,
    earlier: u32,
}

impl WriteFailures {
    /// Takes the count a policy of learner process `learner` carried.
    pub fn saw(&mut self, learner: u32, failures: u32) {
        if learner != self.learner {
            self.earlier += self.current;
            self.learner = learner;
        }
        self.current = failures;
    }

    pub fn total(&self) -> u32 {
        self.earlier + self.current
    }
}

impl Progress {
    /// The episodes the sim has counted so far.
    pub fn episodes(&self) -> EpisodeStats {
        EpisodeStats::from(&self.tick)
    }

    pub fn terrain_accuracy(&self) -> Option<f64> {
        (self.both_areas && self.terrain.scored > 0)
            .then(|| self.terrain.correct as f64 / self.terrain.scored as f64)
    }
}

/// Mean and standard deviation, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    pub mean: f64,
    pub std: f64,
}

/// `summary.json`: one run's totals, and what became of each of its processes (keyed by
/// [`Role::name`](super::Role::name)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub run_id: String,
    pub env_steps: u64,
    pub wall_seconds: f64,
    pub env_steps_per_second: f64,
    pub episodes: u64,
    pub successes: u64,
    pub success_rate: f64,
    /// Over successful episodes; `null` without one.
    pub reach_seconds: Option<MeanStd>,
    pub policy_version: u32,
    /// `null` unless envs see flat and rough ground.
    pub terrain_accuracy: Option<f64>,
    /// Times the estimator refitted its mixture online.
    pub estimator_refits: u32,
    pub pids: BTreeMap<String, u32>,
    /// Each process's last exit status as the OS words it, `null` if it never exited.
    pub exit: BTreeMap<String, Option<String>>,
    pub restarts: BTreeMap<String, u32>,
    pub learner_swaps: u32,
    /// Per learner, checkpoint and metrics writes that failed (a full disk); training went
    /// on and the previous checkpoint stayed whole.
    pub write_failures: BTreeMap<String, u32>,
    /// A switching run's coverage (docs/EXPERIMENT.md E20), from its telemetry CSV; `null`
    /// unless it switched and wrote one.
    #[serde(default)]
    pub switching: Option<common::coverage::Coverage>,
}

impl Summary {
    /// The run's totals from its last progress, after `wall_seconds`.
    pub fn of(
        run_id: &str,
        progress: &Progress,
        decision_dt: f64,
        wall_seconds: f64,
        learner_swaps: u32,
    ) -> Self {
        // On a learner host, which sees no telemetry, the steps its learners learned from.
        let env_steps = progress.tick.env_steps.max(progress.learned_steps);
        let episodes = progress.episodes();
        Self {
            run_id: run_id.to_string(),
            env_steps,
            wall_seconds,
            env_steps_per_second: env_steps as f64 / wall_seconds.max(1e-9),
            episodes: episodes.episodes,
            successes: episodes.successes,
            success_rate: episodes.success_rate(),
            reach_seconds: episodes
                .reach_seconds(decision_dt)
                .map(|(mean, std)| MeanStd { mean, std }),
            policy_version: progress.tick.policy_version.max(progress.learned_version),
            terrain_accuracy: progress.terrain_accuracy(),
            estimator_refits: progress.terrain.refits,
            pids: BTreeMap::new(),
            exit: BTreeMap::new(),
            restarts: BTreeMap::new(),
            learner_swaps,
            write_failures: progress
                .write_failures
                .iter()
                .map(|(slot, w)| (slot.learner_name().to_string(), w.total()))
                .collect(),
            switching: None,
        }
    }

    /// The one line the launcher prints at the end of a run.
    pub fn line(&self, dir: &std::path::Path) -> String {
        format!(
            "run {}: {} env steps in {:.1} s ({} steps/s), {} episodes, success {:.1}%, policy v{}, terrain accuracy {} → {}",
            self.run_id,
            thousands(self.env_steps as f64),
            self.wall_seconds,
            thousands(self.env_steps_per_second),
            thousands(self.episodes as f64),
            100.0 * self.success_rate,
            self.policy_version,
            self.terrain_accuracy
                .map_or("-".into(), |a| format!("{:.1}%", 100.0 * a)),
            dir.display()
        )
    }
}

/// The line a switching run prints about its coverage (docs/EXPERIMENT.md E20), at decision
/// step `dt` seconds.
pub fn coverage_line(c: &common::coverage::Coverage, dt: f64) -> String {
    format!(
        "switching: an estimate on {:.1}% of ticks ({}% right), acted on in {:.1}%, {:.1} switches per 100 m; crossings detected: {}",
        100.0 * c.with_estimate,
        c.right_pct(),
        100.0 * c.acting_on_estimate,
        c.switches_per_100m,
        c.crossings_text(dt).unwrap_or_else(|| "none".into())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reach_time_comes_from_the_tick_sums() {
        // Two successes of 10 and 20 ticks at 0.1 s per tick: 1.5 s ± 0.5 s.
        let p = Progress {
            tick: TickHeader {
                successes: 2,
                reach_ticks: 30,
                reach_ticks_sq: 500,
                ..TickHeader::default()
            },
            ..Progress::default()
        };
        let (mean, std) = p.episodes().reach_seconds(0.1).expect("successes");
        assert!((mean - 1.5).abs() < 1e-12 && (std - 0.5).abs() < 1e-12);
        assert_eq!(Progress::default().episodes().reach_seconds(0.1), None);
    }

    #[test]
    fn write_failures_add_up_over_the_learner_processes_of_a_slot() {
        let mut w = WriteFailures::default();
        w.saw(10, 1);
        w.saw(10, 3);
        assert_eq!(w.total(), 3, "one process reports its running count");
        w.saw(11, 2);
        assert_eq!(w.total(), 5, "a restarted learner counts from 0 again");
    }

    #[test]
    fn the_summary_round_trips_through_json_with_nulls_where_nothing_was_measured() {
        let mut s = Summary::of("r1", &Progress::default(), 0.1, 2.0, 1);
        s.pids.insert("sim".into(), 42);
        s.exit.insert("sim".into(), None);
        let text = serde_json::to_string(&s).expect("json");
        assert!(
            text.contains("\"reach_seconds\":null") && text.contains("\"terrain_accuracy\":null")
        );
        assert_eq!(serde_json::from_str::<Summary>(&text).expect("parse"), s);
    }
}
