//! `sim-proc` on its own: step the envs with a controller and write per-tick telemetry,
//! with no other process involved.

use crate::controllers::{Controller, GoToController, PolicyController, RandomController};
use crate::env::{Env, SharedTerrain, StepInfo};
use crate::task::Ending;
use crate::terrain::Terrain;
use crate::{Batch, SimError};
use anyhow::Context;
use common::episode::EpisodeStats;
use common::{Config, OBS_DIM, Policy, TelemetryRow};
use std::path::{Path, PathBuf};

/// Which controller drives the envs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ControllerKind {
    /// Uniform random wheel commands, each held for `--hold` ticks.
    Random,
    /// Proportional steering toward each target.
    Goto,
    /// A trained policy from `--weights` (mean action).
    Policy,
}

/// Command-line arguments of `sim-proc`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "sim-proc",
    version,
    about = "Steps lavatube robot environments in rapier3d"
)]
pub struct Args {
    /// Config file (TOML); the defaults are used when omitted.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Controller that drives every env.
    #[arg(long, value_enum, default_value = "goto")]
    pub controller: ControllerKind,
    /// Policy file for `--controller policy` (written by the learner's export).
    #[arg(long, required_if_eq("controller", "policy"))]
    pub weights: Option<PathBuf>,
    /// With `--controller policy`: sample each action from the policy's Gaussian with the
    /// run seed's stream, as `sim-proc` in a run does (same seed, same trajectories), instead
    /// of acting with its mean.
    #[arg(long, requires = "weights")]
    pub sample: bool,
    /// Decision steps to run (per env).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: u64,
    /// Ticks a random command is held.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub hold: u32,
    /// Write per-tick telemetry (CSV, one row per env and tick) here; in a run too.
    #[arg(long)]
    pub telemetry: Option<PathBuf>,
    /// Override `run.seed`.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the result (envs, ticks, stepping time, decision steps/s, episode outcomes) as
    /// JSON here, for `lavatube bench`.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Join run ID over shared memory (as the launcher starts it) instead of running alone:
    /// act with the learner's policy and publish rollouts and telemetry.
    #[arg(long, value_parser = common::cli::parse_run_id, conflicts_with_all = ["controller", "weights", "sample", "steps", "json"])]
    pub run_id: Option<String>,
}

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

/// One telemetry row for an env after a step.
pub fn telemetry_row(env: &Env, info: &StepInfo) -> TelemetryRow {
    let p = env.pose();
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
        action_left: l as f64,
        action_right: r as f64,
        reward: info.reward,
        terminated: info.ending.is_some_and(|e| e.terminated()),
        truncated: info.ending.is_some_and(|e| e.truncated()),
        success: info.ending == Some(Ending::Success),
        target_x: info.target[0],
        target_z: info.target[1],
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

/// Runs `steps` decision steps of every env under `controller`, handing each tick's rows to
/// `sink`. Returns the episode summary.
pub fn drive(
    batch: &mut Batch,
    controller: &mut dyn Controller,
    steps: u64,
    mut sink: impl FnMut(&TelemetryRow) -> anyhow::Result<()>,
) -> anyhow::Result<Summary> {
    let n = batch.len();
    let mut obs = vec![[0.0f32; OBS_DIM]; n];
    let mut actions = vec![[0.0f32; 2]; n];
    let mut infos = vec![StepInfo::default(); n];
    batch.observe(&mut obs);
    let mut s = Summary::default();
    for _ in 0..steps {
        for (i, a) in actions.iter_mut().enumerate() {
            *a = controller.act(i, &obs[i]);
        }
        batch.step(&actions, &mut infos, &mut obs);
        for (i, env) in batch.envs.iter().enumerate() {
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

/// The standalone simulator: parse config, build envs, drive them, write telemetry.
pub fn run(args: Args) -> anyhow::Result<Summary> {
    let mut cfg = match &args.config {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    if let Some(seed) = args.seed {
        cfg.run.seed = seed;
    }
    if let Some(run) = &args.run_id {
        crate::serve::serve(&cfg, run, args.telemetry.as_deref())?;
        return Ok(Summary::default());
    }
    let terrain = SharedTerrain::new(Terrain::build(&cfg.sim.terrain)?);
    let mut batch = Batch::new(&cfg.sim, &terrain, cfg.run.seed);
    let limit = cfg.sim.robot.action_limit;
    let mut controller: Box<dyn Controller> = match args.controller {
        ControllerKind::Random => Box::new(RandomController::new(limit, args.hold, cfg.run.seed)),
        ControllerKind::Goto => Box::new(GoToController::new(limit)),
        ControllerKind::Policy => {
            let path = args
                .weights
                .clone()
                .context("--controller policy needs --weights")?;
            let bytes = std::fs::read(&path).map_err(|e| SimError::Weights {
                path: path.clone(),
                reason: e.to_string(),
            })?;
            let policy = Policy::from_bytes(&bytes, &path)?;
            if policy.layout().obs_dim != OBS_DIM || policy.layout().act_dim != common::ACT_DIM {
                return Err(SimError::Weights {
                    path,
                    reason: format!(
                        "network is {:?}, the sim needs obs {OBS_DIM} act {}",
                        policy.layout(),
                        common::ACT_DIM
                    ),
                }
                .into());
            }
            Box::new(PolicyController::new(policy, args.sample, cfg.run.seed))
        }
    };
    tracing::info!(envs = batch.len(), steps = args.steps, controller = ?args.controller, "sim-proc standalone");
    let started = std::time::Instant::now();
    let summary = match &args.telemetry {
        Some(path) => {
            let mut csv = TelemetryCsv::create(path)?;
            let s = drive(&mut batch, controller.as_mut(), args.steps, |row| {
                csv.write(row)
            })?;
            csv.flush()?;
            s
        }
        None => drive(&mut batch, controller.as_mut(), args.steps, |_| Ok(()))?,
    };
    let secs = started.elapsed().as_secs_f64();
    let decision_steps_per_s = (summary.ticks * batch.len() as u64) as f64 / secs;
    tracing::info!(
        ticks = summary.ticks,
        episodes = summary.episodes.episodes,
        successes = summary.episodes.successes,
        stalls = summary.stalls,
        faults = summary.faults,
        decision_steps_per_s,
        "done"
    );
    if let Some(path) = &args.json {
        let result = JsonResult {
            envs: batch.len(),
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
        let mut batch = Batch::new(&cfg, &terrain, 2);
        let s = drive(&mut batch, &mut Idle, 35, |_| Ok(())).expect("drive");
        // Each robot stalls at steps 10, 20 and 30 and never reaches a target.
        assert_eq!(
            (s.episodes.episodes, s.stalls, s.episodes.successes),
            (6, 6, 0)
        );
    }
}
