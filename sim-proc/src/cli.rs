//! The `sim-proc` command line: its arguments, and the dispatch to a run's simulator
//! ([`serve`](crate::serve::serve)) or to the standalone one ([`standalone`](crate::standalone)).

use crate::SimError;
use crate::controllers::{
    Controller, GoToController, PolicyController, RandomController, ReplayController,
};
use crate::outputs::TickFiles;
use crate::serve::RunPart;
use crate::standalone::{Outputs, Summary};
use anyhow::Context;
use clap::Parser;
use common::{ACT_DIM, Config, OBS_DIM, Policy};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Which controller drives the envs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ControllerKind {
    /// Uniform random wheel commands, each held for `--hold` ticks.
    Random,
    /// Proportional steering toward each target.
    Goto,
    /// A trained policy from `--weights` (mean action).
    Policy,
    /// Wheel commands from `--actions`, e.g. a gym client's, replayed exactly.
    Replay,
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
    /// Wheel commands for `--controller replay`: a CSV `tick,env,left,right`, one row per env
    /// and tick, in that order.
    #[arg(long, required_if_eq("controller", "replay"))]
    pub actions: Option<PathBuf>,
    /// Decision steps to run (per env).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: u64,
    /// Ticks a random command is held.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub hold: u32,
    /// Write per-tick telemetry (CSV, one row per env and tick) here; in a run too.
    #[arg(long)]
    pub telemetry: Option<PathBuf>,
    /// Write each env's observation after each step here (CSV `tick,env,obs_0,…,obs_9`; after
    /// an ending, the next episode's first).
    #[arg(long)]
    pub observations: Option<PathBuf>,
    /// In a run: write every env's thinned path, targets and endings here (`track.csv`, what
    /// the run's map is drawn from).
    #[arg(long, requires = "run_id")]
    pub track: Option<PathBuf>,
    /// In a run with `[sim.randomize]`: write the world every episode drew here (`worlds.csv`,
    /// one row per env and episode).
    #[arg(long, requires = "run_id")]
    pub worlds: Option<PathBuf>,
    /// Override `run.seed`.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the result (envs, ticks, stepping time, decision steps/s, episode outcomes) as
    /// JSON here, for `lavatube bench`.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Join run ID over shared memory (as the launcher starts it) instead of running alone:
    /// act with the learner's policy and publish rollouts and telemetry.
    #[arg(long, value_parser = common::cli::parse_run_id, conflicts_with_all = ["controller", "weights", "sample", "actions", "steps", "json", "observations"])]
    pub run_id: Option<String>,
    /// In a run: count env steps on from the newest step count the learners' first
    /// policies carry (their checkpoints'), as `lavatube run --resume` asks.
    #[arg(long, requires = "run_id")]
    pub resume: bool,
    /// In a run: this sim's source id in its rollout chunks, which the learner counts chunks
    /// by. 0 is the sim beside the learner; each sim host of a run across hosts has its own.
    #[arg(long, default_value_t = 0, requires = "run_id")]
    pub source: u32,
}

/// Runs `sim-proc`: joins the run `--run-id` names, or steps the envs alone with the
/// chosen controller.
pub fn run(args: Args) -> anyhow::Result<Summary> {
    let mut cfg = match &args.config {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    if let Some(seed) = args.seed {
        cfg.run.seed = seed;
    }
    if let Some(run) = &args.run_id {
        let part = RunPart {
            source: args.source,
            resume: args.resume,
            files: TickFiles {
                telemetry: args.telemetry.as_deref(),
                track: args.track.as_deref(),
                worlds: args.worlds.as_deref(),
            },
        };
        crate::serve::serve(&cfg, run, &part)?;
        return Ok(Summary::default());
    }
    let mut controller = controller(&args, &cfg)?;
    tracing::info!(envs = cfg.sim.num_envs(), steps = args.steps, controller = ?args.controller, "sim-proc standalone");
    crate::standalone::run(
        &cfg,
        controller.as_mut(),
        args.steps,
        Outputs {
            telemetry: args.telemetry.as_deref(),
            observations: args.observations.as_deref(),
            json: args.json.as_deref(),
        },
    )
}

/// The controller `--controller` names.
fn controller(args: &Args, cfg: &Config) -> anyhow::Result<Box<dyn Controller>> {
    let limit = cfg.sim.robot.action_limit;
    Ok(match args.controller {
        ControllerKind::Random => Box::new(RandomController::new(limit, args.hold, cfg.run.seed)),
        ControllerKind::Goto => Box::new(GoToController::new(limit)),
        ControllerKind::Replay => {
            let path = args
                .actions
                .as_deref()
                .context("--controller replay needs --actions")?;
            let replay = ReplayController::load(path, cfg.sim.num_envs())?;
            if replay.ticks() < args.steps {
                anyhow::bail!(
                    "--steps {} but {} holds {} ticks",
                    args.steps,
                    path.display(),
                    replay.ticks()
                );
            }
            Box::new(replay)
        }
        ControllerKind::Policy => {
            let path = args
                .weights
                .as_deref()
                .context("--controller policy needs --weights")?;
            Box::new(PolicyController::new(
                load_policy(path)?,
                args.sample,
                cfg.run.seed,
            ))
        }
    })
}

/// A policy file with the sim's observation and action sizes.
fn load_policy(path: &Path) -> anyhow::Result<Policy> {
    let bytes = std::fs::read(path).map_err(|e| SimError::Weights {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let policy = Policy::from_bytes(&bytes, path)?;
    if policy.layout().obs_dim != OBS_DIM || policy.layout().act_dim != ACT_DIM {
        return Err(SimError::Weights {
            path: path.to_path_buf(),
            reason: format!(
                "network is {:?}, the sim needs obs {OBS_DIM} act {ACT_DIM}",
                policy.layout()
            ),
        }
        .into());
    }
    Ok(policy)
}

/// The binary's whole job: parse the arguments, run, print any error on one line and map it
/// to the exit code (1 a config error, 2 anything else).
pub fn main() -> ExitCode {
    common::logging::init();
    match run(Args::parse()) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("sim-proc: {e:#}");
            ExitCode::from(if e.downcast_ref::<common::ConfigError>().is_some() {
                1
            } else {
                2
            })
        }
    }
}
