//! What `lavatube bench` measures: the `[bench]` table of `configs/bench.toml` (unknown keys
//! refused, every value checked) and the lavatube config it names for the robot, terrain,
//! PPO and estimator settings. Everything, including the config of every measurement, is
//! validated before the first process starts.

use crate::commands::UserError;
use common::Config;
use common::config::range::{count_in, count_list};
use common::config::{ConfigError, LearnMode, read_toml};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The bench file: only a `[bench]` table.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
struct BenchFile {
    bench: BenchConfig,
}

/// `[bench]`: the measurement matrix and its budgets.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct BenchConfig {
    /// The lavatube config whose robot, terrain, PPO, estimator and seed every measurement
    /// uses, relative to this file. Its env counts, threads, mode and total steps are replaced
    /// per measurement. Default: the built-in defaults.
    pub runtime: Option<PathBuf>,
    /// Env counts to measure, all on rough ground. Each 1 ..= 1024, no repeats. Default [1, 8, 64].
    pub envs: Vec<usize>,
    /// Sim thread counts to measure. Each 1 ..= 64, no repeats. Default [1, 2].
    pub threads: Vec<usize>,
    /// Environment steps (decision steps summed over envs) per measurement, rounded up to
    /// whole rollout chunks. 1 ..= 10^9. Default 32768.
    pub env_steps: u64,
    /// Rollout chunks per measurement at least, so the learner stages average over several
    /// updates and the rate is taken over whole chunk cycles. 2 ..= 10^6. Default 4.
    pub min_chunks: u64,
    /// Times each cell's six stages are measured, in rotation (a–f, a–f, …), so a slow
    /// spell of the machine hits every stage alike; the tables give each stage's median
    /// run. 1 ..= 20. Default 3 (`--quick`: 1). Identical runs here differ by up to 15 %.
    pub repeats: usize,
    /// Messages per payload, transport and phase (latency, throughput) in the shared-memory
    /// versus Unix-socket comparison. 100 ..= 10^7. Default 5000.
    pub transport_messages: usize,
    /// Longest one measurement may take before the bench stops it and fails, seconds.
    /// 10 ..= 86400. Default 900.
    pub timeout_s: u64,
    /// Directory under which each bench gets `<out-dir>/<bench-id>/`: every measurement's
    /// config, logs and metrics, and `bench.json`. Default `runs/bench`.
    pub out_dir: PathBuf,
}

impl Default for BenchConfig {
    fn default() -> Self {
        Self {
            runtime: None,
            envs: vec![1, 8, 64],
            threads: vec![1, 2],
            env_steps: 32_768,
            min_chunks: 4,
            repeats: 3,
            transport_messages: 5000,
            timeout_s: 900,
            out_dir: PathBuf::from("runs/bench"),
        }
    }
}

/// `--quick`: small enough that the whole matrix runs in seconds, to check the tool, not to
/// quote its numbers.
const QUICK_ENV_STEPS: u64 = 512;
const QUICK_MIN_CHUNKS: u64 = 2;
const QUICK_ROLLOUT_TRANSITIONS: usize = 128;
const QUICK_TRANSPORT_MESSAGES: usize = 300;

/// One stage of the pipeline, each adding one piece to the previous.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// a. physics alone: `sim-proc --controller random`, one process.
    Physics,
    /// b. + policy inference: `sim-proc --controller policy` with random weights.
    Policy,
    /// c. + publishing telemetry and rollouts through iceoryx2 to a reader process.
    Publish,
    /// d. + the learner, sync mode.
    Sync,
    /// e. + the learner, async mode.
    Async,
    /// f. + the estimator: the full run, in the runtime config's mode.
    Estimator,
}

impl Stage {
    pub const ALL: [Stage; 6] = [
        Stage::Physics,
        Stage::Policy,
        Stage::Publish,
        Stage::Sync,
        Stage::Async,
        Stage::Estimator,
    ];

    pub fn letter(self) -> char {
        match self {
            Stage::Physics => 'a',
            Stage::Policy => 'b',
            Stage::Publish => 'c',
            Stage::Sync => 'd',
            Stage::Async => 'e',
            Stage::Estimator => 'f',
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Stage::Physics => "physics",
            Stage::Policy => "+ policy",
            Stage::Publish => "+ iceoryx2",
            Stage::Sync => "+ learner sync",
            Stage::Async => "+ learner async",
            Stage::Estimator => "+ estimator",
        }
    }

    /// Whether the stage runs the sim inside a run (shared memory, a reader) rather than alone.
    pub fn joined(self) -> bool {
        !matches!(self, Stage::Physics | Stage::Policy)
    }

    pub fn has_learner(self) -> bool {
        matches!(self, Stage::Sync | Stage::Async | Stage::Estimator)
    }
}

/// One cell of the matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Measurement {
    pub stage: Stage,
    pub envs: usize,
    pub threads: usize,
    /// Which of the cell's `bench.repeats` rounds, from 0.
    pub repeat: usize,
}

impl Measurement {
    /// `d-n8-t2-r0`: names its directory (and, prefixed by the bench id, its run id).
    pub fn label(&self) -> String {
        format!(
            "{}-n{}-t{}-r{}",
            self.stage.letter(),
            self.envs,
            self.threads,
            self.repeat
        )
    }
}

/// A loaded, validated bench: settings, the runtime config, and whether `--quick` shrank it.
#[derive(Debug, Clone)]
pub struct Plan {
    pub bench: BenchConfig,
    pub runtime: Config,
    pub quick: bool,
}

impl BenchConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        count_list("bench.envs", &self.envs, 1, 1024)?;
        count_list("bench.threads", &self.threads, 1, 64)?;
        count_in("bench.env-steps", self.env_steps, 1, 1_000_000_000)?;
        count_in("bench.min-chunks", self.min_chunks, 2, 1_000_000)?;
        count_in("bench.repeats", self.repeats, 1, 20)?;
        count_in(
            "bench.transport-messages",
            self.transport_messages,
            100,
            10_000_000,
        )?;
        count_in("bench.timeout-s", self.timeout_s, 10, 86_400)
    }
}

impl Plan {
    /// Reads the bench file (or takes the defaults), loads the runtime config it names,
    /// applies `--quick`, and validates the config of every measurement. Every error is one
    /// line and a user error.
    pub fn load(path: Option<&Path>, quick: bool) -> anyhow::Result<Self> {
        let bench = match path {
            Some(p) => {
                let mut bench = read_toml::<BenchFile>(p)?.bench;
                // Relative to the bench file, as heightmap paths are to their config.
                if let (Some(r), Some(dir)) = (bench.runtime.as_mut(), p.parent()) {
                    *r = dir.join(&*r);
                }
                bench
            }
            None => BenchConfig::default(),
        };
        bench.validate()?;
        let runtime = match &bench.runtime {
            Some(p) => Config::load(p)?,
            None => Config::default(),
        };
        let mut plan = Self {
            bench,
            runtime,
            quick,
        };
        if quick {
            plan.bench.env_steps = plan.bench.env_steps.min(QUICK_ENV_STEPS);
            plan.bench.min_chunks = QUICK_MIN_CHUNKS;
            plan.bench.repeats = 1;
            plan.bench.transport_messages = QUICK_TRANSPORT_MESSAGES;
            let ppo = &mut plan.runtime.ppo;
            ppo.rollout_transitions = ppo.rollout_transitions.min(QUICK_ROLLOUT_TRANSITIONS);
            ppo.minibatch_size = ppo.minibatch_size.min(ppo.rollout_transitions);
        }
        for m in plan.measurements() {
            plan.config_for(&m, Path::new("."))
                .validate()
                .map_err(|e| UserError(format!("{} envs, {} threads: {e}", m.envs, m.threads)))?;
        }
        Ok(plan)
    }

    /// Every measurement, in the order they run: for each env count and thread count,
    /// `repeats` rounds of the stages a–f back to back, so the stages of one cell see the same
    /// machine conditions and stage c runs right after the stage b it is compared with.
    pub fn measurements(&self) -> Vec<Measurement> {
        let mut out = Vec::new();
        for &envs in &self.bench.envs {
            for &threads in &self.bench.threads {
                for repeat in 0..self.bench.repeats {
                    for stage in Stage::ALL {
                        out.push(Measurement {
                            stage,
                            envs,
                            threads,
                            repeat,
                        });
                    }
                }
            }
        }
        out
    }

    /// Decision steps per env of one rollout chunk at `envs` envs.
    pub fn rollout_steps(&self, envs: usize) -> u64 {
        self.runtime.ppo.rollout_steps(envs) as u64
    }

    /// Rollout chunks per measurement at `envs` envs: enough for `env-steps`, at least
    /// `min-chunks`.
    pub fn chunks(&self, envs: usize) -> u64 {
        let per_chunk = self.rollout_steps(envs) * envs as u64;
        self.bench
            .env_steps
            .div_ceil(per_chunk)
            .max(self.bench.min_chunks)
    }

    /// Ticks (decision steps per env) of every stage at `envs` envs: whole chunks, so the
    /// standalone stages step exactly as many ticks as the sim in a run does.
    pub fn ticks(&self, envs: usize) -> u64 {
        self.chunks(envs) * self.rollout_steps(envs)
    }

    /// The learning mode of a stage; `None` where no learner runs.
    pub fn mode(&self, stage: Stage) -> Option<LearnMode> {
        match stage {
            Stage::Sync => Some(LearnMode::Sync),
            // Stage c has no learner, and a sync sim would wait for one after its first chunk.
            Stage::Publish | Stage::Async => Some(LearnMode::Async),
            Stage::Estimator => Some(self.runtime.run.mode),
            Stage::Physics | Stage::Policy => None,
        }
    }

    /// The resolved config of one measurement, writing into `dir`.
    pub fn config_for(&self, m: &Measurement, dir: &Path) -> Config {
        let mut cfg = self.runtime.clone();
        cfg.sim.only_in(common::AreaKind::Rough, m.envs);
        cfg.sim.threads = m.threads;
        cfg.run.total_steps = self.ticks(m.envs) * m.envs as u64;
        cfg.run.out_dir = dir.to_path_buf();
        if let Some(mode) = self.mode(m.stage) {
            cfg.run.mode = mode;
        }
        cfg
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::AreaKind;

    fn load(body: &str) -> anyhow::Result<Plan> {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("bench.toml");
        std::fs::write(&path, body).expect("write");
        Plan::load(Some(&path), false)
    }

    #[test]
    fn defaults_measure_the_issue_matrix() {
        let plan = Plan::load(None, false).expect("defaults");
        let all = plan.measurements();
        assert_eq!(
            all.len(),
            3 * 2 * 3 * 6,
            "envs × threads × repeats × stages"
        );
        // A cell's rounds follow each other, each round every stage in order.
        let first: Vec<String> = all[5..8].iter().map(Measurement::label).collect();
        assert_eq!(first, ["f-n1-t1-r0", "a-n1-t1-r1", "b-n1-t1-r1"]);
        // 2048 transitions per chunk (2048 ticks at 1 env, 32 at 64): 32768 env steps are 16.
        assert_eq!((plan.ticks(1), plan.ticks(64)), (16 * 2048, 16 * 32));
        let m = Measurement {
            stage: Stage::Publish,
            envs: 8,
            threads: 2,
            repeat: 1,
        };
        let cfg = plan.config_for(&m, Path::new("x"));
        assert_eq!(
            (
                cfg.sim.envs_in(AreaKind::Flat),
                cfg.sim.envs_in(AreaKind::Rough),
                cfg.sim.threads
            ),
            (0, 8, 2)
        );
        assert_eq!(
            cfg.run.mode,
            LearnMode::Async,
            "no learner: a sync sim would wait"
        );
        assert_eq!(cfg.run.total_steps, plan.ticks(8) * 8);
        assert_eq!(m.label(), "c-n8-t2-r1");
    }

    #[test]
    fn quick_shrinks_every_budget() {
        let plan = Plan::load(None, true).expect("quick");
        assert_eq!(
            plan.runtime.ppo.rollout_transitions,
            QUICK_ROLLOUT_TRANSITIONS
        );
        assert!(plan.ticks(1) <= QUICK_ENV_STEPS && plan.ticks(64) <= 8);
        assert_eq!(plan.bench.repeats, 1);
    }

    #[test]
    fn bad_input_names_the_field_or_position() {
        let e = load("[bench]\nenvs = [1, 0]\n").expect_err("zero envs");
        assert_eq!(
            e.to_string(),
            "config field `bench.envs` = [1, 0]: 0 is not in [1, 1024]"
        );
        let e = load("[bench]\nenvs = [8, 8]\n").expect_err("repeat");
        assert!(e.to_string().contains("lists a value twice"), "{e}");
        let e = load("[bench]\nthread = [1]\n").expect_err("unknown key");
        let msg = e.to_string();
        assert!(msg.contains(":2:1: unknown field `thread`"), "{msg}");
        assert!(!msg.contains('\n'));
        let e = load("[sim]\nenvs = { flat = 1 }\n")
            .expect_err("runtime keys belong in the runtime file");
        assert!(e.to_string().contains("unknown field `sim`"), "{e}");
    }

    #[test]
    fn runtime_is_relative_to_the_bench_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("rt.toml"), "[ppo]\nepochs = 3\n").expect("write");
        let path = dir.path().join("bench.toml");
        std::fs::write(&path, "[bench]\nruntime = \"rt.toml\"\n").expect("write");
        let plan = Plan::load(Some(&path), false).expect("load");
        assert_eq!(plan.runtime.ppo.epochs, 3);
        std::fs::write(&path, "[bench]\nruntime = \"missing.toml\"\n").expect("write");
        let e = Plan::load(Some(&path), false).expect_err("missing");
        assert!(e.to_string().starts_with("cannot read config "), "{e}");
    }

    #[test]
    fn a_runtime_that_cannot_fit_a_cell_is_refused_up_front() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Valid for its own 9 envs (8 × 9 = 72 transitions per chunk), but 1 env collects
        // only 64, fewer than a minibatch.
        std::fs::write(
            dir.path().join("rt.toml"),
            "[ppo]\nrollout-transitions = 64\nminibatch-size = 70\n",
        )
        .expect("write");
        let path = dir.path().join("bench.toml");
        std::fs::write(&path, "[bench]\nruntime = \"rt.toml\"\nenvs = [1]\n").expect("write");
        let e = Plan::load(Some(&path), false).expect_err("minibatch");
        assert_eq!(
            e.to_string(),
            "1 envs, 1 threads: config field `ppo.minibatch-size` = 70: must be in [1, 64]"
        );
    }
}
