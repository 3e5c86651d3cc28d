//! `[ppo]`: the learner's hyperparameters and checkpointing.

use super::ConfigError;
use super::range::invalid;
use super::setting::{Setting, choices, count, flag, real, settings};
use serde::{Deserialize, Serialize};

settings! {
    /// PPO hyperparameters (SPEC S6, Table 2) and implementation details.
    pub struct PpoConfig {
        /// Transitions per update, summed over envs (SPEC S6, interpretation).
        pub rollout_transitions: usize = 2048 => count(64, 1_000_000), "transitions", Essential;
        /// Minibatch size ("batch size" in ML-Agents); at most the rollout's batch.
        pub minibatch_size: usize = 64 => count(1, 1_000_000), "transitions", Essential;
        /// Epochs per update.
        pub epochs: usize = 10 => count(1, 100), "", Advanced;
        /// Adam learning rate.
        pub learning_rate: f64 = 3e-4 => real(1e-12, 1.0), "", Essential;
        /// Decay the learning rate linearly to 0 over `run.total-steps`.
        pub anneal_lr: bool = true => flag(), "", Advanced;
        /// Adam epsilon.
        pub adam_eps: f64 = 1e-5 => real(1e-12, 1.0), "", Advanced;
        /// Discount γ.
        pub gamma: f64 = 0.99 => real(0.0, 1.0), "", Advanced;
        /// GAE λ.
        pub gae_lambda: f64 = 0.95 => real(0.0, 1.0), "", Advanced;
        /// Surrogate clip ε.
        pub clip_coef: f64 = 0.2 => real(1e-6, 1.0), "", Advanced;
        /// Clip the value loss around the old value too.
        pub clip_vloss: bool = false => flag(), "", Research;
        /// Entropy coefficient.
        pub ent_coef: f64 = 5e-4 => real(0.0, 1.0), "", Advanced;
        /// Value-loss coefficient.
        pub vf_coef: f64 = 0.5 => real(0.0, 10.0), "", Advanced;
        /// Global gradient-norm clip.
        pub max_grad_norm: f64 = 0.5 => real(1e-6, 1000.0), "", Advanced;
        /// Normalise advantages per minibatch.
        pub norm_adv: bool = true => flag(), "", Research;
        /// Stop an update's epochs early when approx KL exceeds this; unset: never.
        pub target_kl: Option<f64> = None => real(1e-9, 10.0), "", Research;
        /// Hidden layer widths of actor and critic, 1 to 4 layers (SPEC S6, interpretation:
        /// ML-Agents' 2 × 128).
        pub hidden: Vec<usize> = vec![128, 128] => count(1, 4096), "units", Advanced;
        /// Orthogonal init (hidden √2, policy head 0.01, value head 1).
        pub ortho_init: bool = true => flag(), "", Research;
        /// Initial log standard deviation of the action distribution.
        pub init_log_std: f64 = 0.0 => real(-5.0, 2.0), "", Advanced;
        /// Running observation normalisation.
        pub obs_norm: bool = true => flag(), "", Research;
        /// Clip of normalised observations.
        pub obs_clip: f64 = 10.0 => real(1e-3, 100.0), "σ", Advanced;
        /// Write a checkpoint every this many updates: at 1 a learner killed at any moment
        /// loses no update and its replacement continues the version sequence exactly
        /// (DESIGN §4); larger values trade that for less disk traffic.
        pub checkpoint_every: usize = 1 => count(1, 1_000_000), "updates", Advanced;
        /// Checkpoints kept (oldest removed).
        pub keep_checkpoints: usize = 3 => count(1, 1000), "checkpoints", Advanced;
        /// Also keep, for good, every checkpoint whose update count is a multiple of this
        /// (a multiple of `checkpoint-every`): a learning run's milestones, to pick the best
        /// of by validation (`reproduce.specialist-candidates`); 0: none.
        pub milestone_every: usize = 0 => count(0, 1_000_000), "updates", Advanced;
        /// In async mode, drop transitions more than this many policy versions old.
        pub max_policy_lag: u32 = 4 => count(0, 1000), "versions", Advanced;
        /// How an update takes gradients: `fused` (a hand-derived backward pass, on
        /// `threads` workers) or `burn` (burn's autodiff, one thread).
        pub engine: PpoEngine = PpoEngine::Fused => choices::<PpoEngine>(), "", Advanced;
        /// Workers of a fused update; 0 picks ([`PpoConfig::update_threads`]).
        pub threads: usize = 0 => count(0, 256), "threads", Advanced;
        /// Rows per gradient shard of a fused update: weights depend on it, not on `threads`;
        /// a shard feeds two threads at most, and larger shards run faster.
        pub shard_size: usize = 32 => count(1, 4096), "rows", Advanced;
    }
}

/// How the learner takes an update's gradients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PpoEngine {
    /// Forward and backward written out for the MLPs and PPO's loss, on host buffers, split
    /// into shards over worker threads.
    Fused,
    /// burn's autodiff on its CPU backend, one minibatch at a time on one thread.
    Burn,
}

impl Setting for PpoEngine {}

impl PpoConfig {
    /// Steps per env per rollout: enough that T × N covers `rollout-transitions`.
    pub fn rollout_steps(&self, num_envs: usize) -> usize {
        self.rollout_transitions.div_ceil(num_envs.max(1))
    }

    /// The fused update's workers: `threads`, or when that is 0 the cores left to each of
    /// the run's `learners` (at least 1): every core in sync mode, where the sim waits for
    /// the update, and those the sim's `sim_threads` leave free in async mode.
    pub fn update_threads(&self, sync: bool, sim_threads: usize, learners: usize) -> usize {
        if self.threads > 0 {
            return self.threads;
        }
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        let free = if sync {
            cores
        } else {
            cores.saturating_sub(sim_threads)
        };
        (free / learners.max(1)).max(1)
    }

    /// The rules between fields (each field's own range is [`super::setting::Setting::check`]'s);
    /// `num_envs`: the sim's, whose rollout batch bounds the minibatch.
    pub(super) fn validate(&self, num_envs: usize) -> Result<(), ConfigError> {
        let batch = self.rollout_steps(num_envs) * num_envs;
        if self.minibatch_size > batch {
            return Err(invalid(
                "ppo.minibatch-size",
                self.minibatch_size,
                format!("must be in [1, {batch}]"),
            ));
        }
        if self.hidden.is_empty() || self.hidden.len() > crate::policy::MAX_HIDDEN {
            return Err(invalid(
                "ppo.hidden",
                &self.hidden,
                format!("needs 1 ..= {} layers", crate::policy::MAX_HIDDEN),
            ));
        }
        if !self.milestone_every.is_multiple_of(self.checkpoint_every) {
            return Err(invalid(
                "ppo.milestone-every",
                self.milestone_every,
                format!(
                    "must be a multiple of ppo.checkpoint-every ({}): only written checkpoints can be kept",
                    self.checkpoint_every
                ),
            ));
        }
        if self.engine == PpoEngine::Burn && self.threads > 1 {
            return Err(invalid(
                "ppo.threads",
                self.threads,
                "the burn engine runs on one thread; set ppo.engine = \"fused\" to use more",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rollout_steps_cover_the_batch() {
        let p = PpoConfig::default();
        assert_eq!(p.rollout_steps(8), 256);
        assert_eq!(p.rollout_steps(9), 228); // 228 × 9 = 2052 ≥ 2048
    }

    #[test]
    fn update_threads_are_the_cores_the_sim_leaves() {
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        let mut p = PpoConfig::default();
        assert_eq!(p.update_threads(true, 2, 1), cores);
        assert_eq!(p.update_threads(false, 1, 1), (cores - 1).max(1));
        assert_eq!(p.update_threads(false, cores + 4, 1), 1);
        assert_eq!(p.update_threads(true, 2, 2 * cores), 1);
        p.threads = 3;
        assert_eq!(p.update_threads(false, 64, 3), 3);
    }

    #[test]
    fn the_burn_engine_takes_one_thread() {
        let mut p = PpoConfig {
            engine: PpoEngine::Burn,
            threads: 2,
            ..PpoConfig::default()
        };
        let err = p.validate(8).expect_err("burn on two threads").to_string();
        assert!(
            err.contains("ppo.threads") && err.contains("fused"),
            "{err}"
        );
        p.threads = 1;
        p.validate(8).expect("burn on one thread");
    }
}
