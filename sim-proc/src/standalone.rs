//! `sim-proc` on its own: step the envs with a controller and write per-tick telemetry,
//! with no other process involved.

use crate::Fleet;
use crate::controllers::Controller;
use crate::env::{SharedTerrain, StepInfo};
use crate::task::Ending;
use crate::telemetry_csv::{TelemetryCsv, telemetry_row};
use crate::terrain::Terrain;
use anyhow::Context;
use common::episode::EpisodeStats;
use common::{Config, OBS_DIM, TelemetryRow};
use std::path::Path;

/// What `--json` writes. The time covers stepping only (not building the terrain), so it
/// compares with the stepping rate a run's telemetry shows.
#[derive(Debug, serde::Serialize)]
struct JsonResult {
    envs: usize,
    ticks: u64,
    episodes: u64,
    successes: u64,
    stalls: u64,
    faults: u64,
    /// Mean decision steps of successful episodes; 0 without any.
    mean_reach_steps: f64,
    stepping_seconds: f64,
    decision_steps_per_s: f64,
}

/// Episode outcomes over a run.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct Summary {
    pub ticks: u64,
    pub episodes: EpisodeStats,
    /// Episodes ended by the stall rule (`sim.task.stall-steps`).
    pub stalls: u64,
    pub faults: u64,
}

/// Runs `steps` decision steps of every env under `controller`, handing each tick's rows to
/// `sink`. Returns the episode summary.
pub fn drive(
    fleet: &mut Fleet,
    controller: &mut dyn Controller,
    steps: u64,
    mut sink: impl FnMut(&TelemetryRow) -> anyhow::Result<()>,
) -> anyhow::Result<Summary> {
    let n = fleet.len();
    let mut obs = vec![[0.0f32; OBS_DIM]; n];
    let mut actions = vec![[0.0f32; 2]; n];
    let mut infos = vec![StepInfo::default(); n];
    fleet.observe(&mut obs);
    let mut s = Summary::default();
    for _ in 0..steps {
        for (i, a) in actions.iter_mut().enumerate() {
            *a = controller.act(i, &obs[i]);
        }
        fleet.step(&actions, &mut infos, &mut obs);
        for (i, env) in fleet.envs.iter().enumerate() {
            let info = &infos[i];
            sink(&telemetry_row(env, info))?;
            if let Some(end) = info.ending {
                s.episodes
                    .record(end == Ending::Success, u64::from(info.episode_steps));
                s.stalls += u64::from(end == Ending::Stalled);
            }
        }
        s.ticks += 1;
    }
    s.faults = infos.iter().map(|i| i.faults).sum();
    Ok(s)
}

/// The standalone simulator: build the envs, drive them `steps` decision steps under
/// `controller`, write the telemetry CSV and the `--json` result where asked.
pub fn run(
    cfg: &Config,
    controller: &mut dyn Controller,
    steps: u64,
    telemetry: Option<&Path>,
    json: Option<&Path>,
) -> anyhow::Result<Summary> {
    let terrain = SharedTerrain::new(Terrain::build(&cfg.sim.terrain)?);
    let mut fleet = Fleet::new(&cfg.sim, &terrain, cfg.run.seed);
    let started = std::time::Instant::now();
    let summary = match telemetry {
        Some(path) => {
            let mut csv = TelemetryCsv::create(path)?;
            let s = drive(&mut fleet, controller, steps, |row| csv.write(row))?;
            csv.flush()?;
            s
        }
        None => drive(&mut fleet, controller, steps, |_| Ok(()))?,
    };
    let secs = started.elapsed().as_secs_f64();
    let decision_steps_per_s = (summary.ticks * fleet.len() as u64) as f64 / secs;
    tracing::info!(
        ticks = summary.ticks,
        episodes = summary.episodes.episodes,
        successes = summary.episodes.successes,
        stalls = summary.stalls,
        faults = summary.faults,
        decision_steps_per_s,
        "done"
    );
    if let Some(path) = json {
        let result = JsonResult {
            envs: fleet.len(),
            ticks: summary.ticks,
            episodes: summary.episodes.episodes,
            successes: summary.episodes.successes,
            stalls: summary.stalls,
            faults: summary.faults,
            mean_reach_steps: summary
                .episodes
                .reach_seconds(1.0)
                .map_or(0.0, |(mean, _)| mean),
            stepping_seconds: secs,
            decision_steps_per_s,
        };
        let text = serde_json::to_string_pretty(&result).context("cannot serialise the result")?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::SimConfig;

    /// Sends the wheels nothing: the robot stands where it landed.
    struct Idle;

    impl Controller for Idle {
        fn act(&mut self, _env: usize, _obs: &[f32; OBS_DIM]) -> [f32; common::ACT_DIM] {
            [0.0; common::ACT_DIM]
        }
    }

    #[test]
    fn the_summary_counts_stalls() {
        let mut cfg = SimConfig {
            flat_envs: 2,
            threads: 1,
            ..SimConfig::default()
        };
        cfg.task.stall_steps = 10;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain));
        let mut fleet = Fleet::new(&cfg, &terrain, 2);
        let s = drive(&mut fleet, &mut Idle, 35, |_| Ok(())).expect("drive");
        // Each robot stalls at steps 10, 20 and 30 and never reaches a target.
        assert_eq!(
            (s.episodes.episodes, s.stalls, s.episodes.successes),
            (6, 6, 0)
        );
    }
}
