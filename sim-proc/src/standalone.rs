//! `sim-proc` on its own: step the envs with a controller and write per-tick telemetry,
//! with no other process involved.

use crate::Fleet;
use crate::controllers::{Controller, StepOut};
use crate::env::{SharedTerrain, StepInfo};
use crate::task::Ending;
use crate::telemetry_csv::{TelemetryCsv, telemetry_row};
use crate::terrain::Terrain;
use anyhow::Context;
use common::episode::EpisodeStats;
use common::{ACT_DIM, Config, OBS_DIM, TelemetryRow};
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

/// Runs `steps` decision steps of every env under `controller`, handing each env's row of
/// each tick to `sink` with the observation the step left it (the next episode's first after
/// an ending). Returns the episode summary.
pub fn drive(
    fleet: &mut Fleet,
    controller: &mut dyn Controller,
    steps: u64,
    mut sink: impl FnMut(&TelemetryRow, &[f32; OBS_DIM]) -> anyhow::Result<()>,
) -> anyhow::Result<Summary> {
    let n = fleet.len();
    let mut obs = vec![[0.0f32; OBS_DIM]; n];
    let mut next = vec![[0.0f32; OBS_DIM]; n];
    let mut actions = vec![[0.0f32; ACT_DIM]; n];
    let mut infos = vec![StepInfo::default(); n];
    fleet.observe(&mut obs);
    let mut s = Summary::default();
    for _ in 0..steps {
        let out = StepOut {
            actions: &mut actions,
            infos: &mut infos,
            next_obs: &mut next,
        };
        controller.step(fleet, &obs, out);
        std::mem::swap(&mut obs, &mut next);
        for (i, env) in fleet.envs.iter().enumerate() {
            let info = &infos[i];
            sink(&telemetry_row(env, info, (None, None)), &obs[i])?;
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

/// Where the standalone simulator writes what it did.
#[derive(Debug, Clone, Copy, Default)]
pub struct Outputs<'a> {
    /// The telemetry CSV (`--telemetry`).
    pub telemetry: Option<&'a Path>,
    /// Each env's observation after each step (`--observations`).
    pub observations: Option<&'a Path>,
    /// The `--json` result.
    pub json: Option<&'a Path>,
}

/// The standalone simulator: build the envs, drive them `steps` decision steps under
/// `controller`, write the files `out` names.
pub fn run(
    cfg: &Config,
    controller: &mut dyn Controller,
    steps: u64,
    out: Outputs,
) -> anyhow::Result<Summary> {
    let terrain = SharedTerrain::new(Terrain::build(&cfg.sim.terrain)?, cfg.sim.terrain.collider);
    let mut fleet = Fleet::new(&cfg.sim, &terrain, cfg.run.seed);
    let started = std::time::Instant::now();
    let mut csv = out.telemetry.map(TelemetryCsv::create).transpose()?;
    let mut observations = out.observations.map(ObservationCsv::create).transpose()?;
    let summary = drive(&mut fleet, controller, steps, |row, obs| {
        if let Some(csv) = csv.as_mut() {
            csv.write(row)?;
        }
        if let Some(o) = observations.as_mut() {
            o.write(row, obs)?;
        }
        Ok(())
    })?;
    if let Some(csv) = csv.as_mut() {
        csv.flush()?;
    }
    if let Some(o) = observations.as_mut() {
        o.flush()?;
    }
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
    if let Some(path) = out.json {
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

/// `--observations`: `tick,env,obs_0,…,obs_9`, one row per env and tick, each value written
/// so that it reads back to the same f32.
struct ObservationCsv {
    path: std::path::PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl ObservationCsv {
    fn create(path: &Path) -> anyhow::Result<Self> {
        let file = std::fs::File::create(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut o = Self {
            path: path.to_path_buf(),
            out: std::io::BufWriter::new(file),
        };
        let names: Vec<String> = (0..OBS_DIM).map(|k| format!("obs_{k}")).collect();
        o.line(format_args!("tick,env,{}", names.join(",")))?;
        Ok(o)
    }

    fn write(&mut self, row: &TelemetryRow, obs: &[f32; OBS_DIM]) -> anyhow::Result<()> {
        let values: Vec<String> = obs.iter().map(f32::to_string).collect();
        self.line(format_args!(
            "{},{},{}",
            row.tick,
            row.env,
            values.join(",")
        ))
    }

    fn line(&mut self, text: std::fmt::Arguments) -> anyhow::Result<()> {
        use std::io::Write;
        writeln!(self.out, "{text}")
            .with_context(|| format!("cannot write {}", self.path.display()))
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        use std::io::Write;
        self.out
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))
    }
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
            envs: [(common::AreaKind::Flat, 2)].into(),
            threads: 1,
            ..SimConfig::default()
        };
        cfg.task.stall_steps = 10;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut fleet = Fleet::new(&cfg, &terrain, 2);
        let s = drive(&mut fleet, &mut Idle, 35, |_, _| Ok(())).expect("drive");
        // Each robot stalls at steps 10, 20 and 30 and never reaches a target.
        assert_eq!(
            (s.episodes.episodes, s.stalls, s.episodes.successes),
            (6, 6, 0)
        );
    }
}
