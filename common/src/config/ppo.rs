//! `[ppo]`: the learner's hyperparameters and checkpointing.

use super::ConfigError;
use super::range::{count_in, in_range, invalid};
use serde::{Deserialize, Serialize};

/// PPO hyperparameters (SPEC S6, Table 2) and implementation details.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct PpoConfig {
    /// Transitions per update, summed over envs (SPEC S6, interpretation). 64 ..= 10^6. Default 2048.
    pub rollout_transitions: usize,
    /// Minibatch size ("batch size" in ML-Agents). 1 ..= rollout. Default 64.
    pub minibatch_size: usize,
    /// Epochs per update. 1 ..= 100. Default 10.
    pub epochs: usize,
    /// Adam learning rate. (0, 1]. Default 3e-4.
    pub learning_rate: f64,
    /// Decay the learning rate linearly to 0 over `run.total-steps`. Default true.
    pub anneal_lr: bool,
    /// Adam epsilon. (0, 1]. Default 1e-5.
    pub adam_eps: f64,
    /// Discount γ. [0, 1]. Default 0.99.
    pub gamma: f64,
    /// GAE λ. [0, 1]. Default 0.95.
    pub gae_lambda: f64,
    /// Surrogate clip ε. (0, 1]. Default 0.2.
    pub clip_coef: f64,
    /// Clip the value loss around the old value too. Default false.
    pub clip_vloss: bool,
    /// Entropy coefficient. [0, 1]. Default 5e-4.
    pub ent_coef: f64,
    /// Value-loss coefficient. [0, 10]. Default 0.5.
    pub vf_coef: f64,
    /// Global gradient-norm clip. (0, 1000]. Default 0.5.
    pub max_grad_norm: f64,
    /// Normalise advantages per minibatch. Default true.
    pub norm_adv: bool,
    /// Stop an update's epochs early when approx KL exceeds this. Default none.
    pub target_kl: Option<f64>,
    /// Hidden layer widths of actor and critic (SPEC S6, interpretation: ML-Agents' 2 × 128).
    pub hidden: Vec<usize>,
    /// Orthogonal init (hidden √2, policy head 0.01, value head 1). Default true.
    pub ortho_init: bool,
    /// Initial log standard deviation of the action distribution. [-5, 2]. Default 0.
    pub init_log_std: f64,
    /// Running observation normalisation. Default true.
    pub obs_norm: bool,
    /// Clip of normalised observations. (0, 100]. Default 10.
    pub obs_clip: f64,
    /// Write a checkpoint every this many updates. 1 ..= 10^6. Default 1: a learner killed
    /// at any moment then loses no update and its replacement continues the version
    /// sequence exactly (DESIGN §4); larger values trade that for less disk traffic.
    pub checkpoint_every: usize,
    /// Checkpoints kept (oldest removed). 1 ..= 1000. Default 3.
    pub keep_checkpoints: usize,
    /// Also keep, for good, every checkpoint whose update count is a multiple of this: a
    /// learning run's milestones, to pick the best of by validation (`lavatube reproduce`
    /// does, see `reproduce.specialist-candidates`). 0 or a multiple of `checkpoint-every`,
    /// ..= 10^6. Default 0: none.
    pub milestone_every: usize,
    /// In async mode, drop transitions more than this many policy versions old. 0 ..= 1000. Default 4.
    pub max_policy_lag: u32,
    /// How an update takes gradients: "fused" (a hand-derived backward pass, on `threads`
    /// workers) or "burn" (burn's autodiff, one thread). Default "fused".
    pub engine: PpoEngine,
    /// Workers of a fused update. 0 ..= 256; 0 picks ([`PpoConfig::update_threads`]). Default 0.
    pub threads: usize,
    /// Rows per gradient shard of a fused update: weights depend on it, not on `threads`;
    /// a shard feeds two threads at most, and larger shards run faster. 1 ..= 4096. Default 32.
    pub shard_size: usize,
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

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            rollout_transitions: 2048,
            minibatch_size: 64,
            epochs: 10,
            learning_rate: 3e-4,
            anneal_lr: true,
            adam_eps: 1e-5,
            gamma: 0.99,
            gae_lambda: 0.95,
            clip_coef: 0.2,
            clip_vloss: false,
            ent_coef: 5e-4,
            vf_coef: 0.5,
            max_grad_norm: 0.5,
            norm_adv: true,
            target_kl: None,
            hidden: vec![128, 128],
            ortho_init: true,
            init_log_std: 0.0,
            obs_norm: true,
            obs_clip: 10.0,
            checkpoint_every: 1,
            keep_checkpoints: 3,
            milestone_every: 0,
            max_policy_lag: 4,
            engine: PpoEngine::Fused,
            threads: 0,
            shard_size: 32,
        }
    }
}

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

    /// `num_envs`: the sim's, whose rollout batch bounds the minibatch.
    pub(super) fn validate(&self, num_envs: usize) -> Result<(), ConfigError> {
        count_in(
            "ppo.rollout-transitions",
            self.rollout_transitions,
            64,
            1_000_000,
        )?;
        let batch = self.rollout_steps(num_envs) * num_envs;
        count_in("ppo.minibatch-size", self.minibatch_size, 1, batch)?;
        count_in("ppo.epochs", self.epochs, 1, 100)?;
        in_range("ppo.learning-rate", self.learning_rate, 1e-12, 1.0)?;
        in_range("ppo.adam-eps", self.adam_eps, 1e-12, 1.0)?;
        in_range("ppo.gamma", self.gamma, 0.0, 1.0)?;
        in_range("ppo.gae-lambda", self.gae_lambda, 0.0, 1.0)?;
        in_range("ppo.clip-coef", self.clip_coef, 1e-6, 1.0)?;
        in_range("ppo.ent-coef", self.ent_coef, 0.0, 1.0)?;
        in_range("ppo.vf-coef", self.vf_coef, 0.0, 10.0)?;
        in_range("ppo.max-grad-norm", self.max_grad_norm, 1e-6, 1000.0)?;
        if let Some(kl) = self.target_kl {
            in_range("ppo.target-kl", kl, 1e-9, 10.0)?;
        }
        if self.hidden.is_empty() || self.hidden.len() > crate::policy::MAX_HIDDEN {
            return Err(invalid(
                "ppo.hidden",
                &self.hidden,
                format!("needs 1 ..= {} layers", crate::policy::MAX_HIDDEN),
            ));
        }
        for &h in &self.hidden {
            count_in("ppo.hidden", h, 1, 4096)?;
        }
        in_range("ppo.init-log-std", self.init_log_std, -5.0, 2.0)?;
        in_range("ppo.obs-clip", self.obs_clip, 1e-3, 100.0)?;
        count_in("ppo.checkpoint-every", self.checkpoint_every, 1, 1_000_000)?;
        count_in("ppo.keep-checkpoints", self.keep_checkpoints, 1, 1000)?;
        count_in("ppo.milestone-every", self.milestone_every, 0, 1_000_000)?;
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
        count_in("ppo.max-policy-lag", self.max_policy_lag, 0, 1000)?;
        count_in("ppo.threads", self.threads, 0, 256)?;
        count_in("ppo.shard-size", self.shard_size, 1, 4096)?;
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
