//! PPO (SPEC S6), read top to bottom like CleanRL's `ppo_continuous_action.py`:
//!
//! 1. `acting`: the policy acts (mean or sampled action) and the critic values observations;
//! 2. `batch`: one critic pass and GAE over the rollout, flattened to CleanRL's `b_*`
//!    arrays, and the `b_inds` an update may train on;
//! 3. `update`: epochs of shuffled minibatches, then the update's metrics;
//! 4. `fused` (the default engine): the epochs with a hand-derived backward pass, each
//!    minibatch's gradient split into shards over worker threads;
//! 5. `minibatch` (the burn engine): one minibatch's clipped surrogate, optional value clipping and entropy
//!    bonus, global gradient-norm clipping and an Adam step with a linearly decaying
//!    learning rate.
//!
//! Observation normalisation: an update trains on the statistics the behaviour policy acted
//! with (the ones last shipped), so the first epoch's ratios start at 1; afterwards the
//! statistics absorb the rollout's observations and ship with the new weights.

mod acting;
mod batch;
mod fused;
mod minibatch;
#[cfg(test)]
pub(crate) mod tests;
mod update;

use burn::tensor::Device;
use common::config::{Config, LearnMode, PolicySlot, PpoConfig, PpoEngine};
use common::policy::PolicyLayout;
use common::{ACT_DIM, OBS_DIM, Rng, Transition};
use serde::{Deserialize, Serialize};

pub use acting::SampledAction;

use crate::LearnerError;
use crate::adam::Adam;
use crate::metrics::EpisodeOutcome;
use crate::net::NetShape;
use crate::obs_norm::RunningMeanStd;

/// Width of a network input row: the observation and the bias unit.
const IN: usize = OBS_DIM + 1;

/// One chunk of experience, as the `rollout` service delivers it.
#[derive(Debug, Clone, Copy)]
pub struct Rollout<'a> {
    /// `T × N` transitions in `[step][env]` order; every row lists the envs in the same order.
    pub transitions: &'a [Transition],
    /// Each env's observation after its last step, `[envs]`, in the rows' env order.
    pub bootstrap_obs: &'a [[f32; OBS_DIM]],
    /// Episodes that ended during the chunk, with outcomes only the simulator knows.
    pub episodes: &'a [EpisodeOutcome],
}

/// How far training has come; all three survive checkpoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Counters {
    /// Updates done.
    pub update: u64,
    /// Transitions received (trained on or dropped as stale); also the position of the
    /// learning-rate schedule.
    pub global_step: u64,
    /// Version of the current weights (0: initial); +1 per update.
    pub policy_version: u32,
}

/// The actor as `common::policy` lays it out: observation mean and variance, then the actor's
/// parameters (the first `actor_len` of the learner's flat order).
pub(crate) fn shipped_weights(
    obs_norm: &RunningMeanStd,
    shape: &NetShape,
    params: &[f32],
) -> Vec<f32> {
    let (mean, var) = obs_norm.shipped();
    let mut w = Vec::with_capacity(mean.len() + var.len() + shape.actor_len());
    w.extend(mean);
    w.extend(var);
    w.extend_from_slice(&params[..shape.actor_len()]);
    w
}

/// The PPO learner: actor, critic, optimizer, observation statistics and RNG.
pub struct Learner {
    pub(crate) ppo: PpoConfig,
    pub(crate) total_steps: u64,
    pub(crate) decision_dt: f64,
    pub(crate) shape: NetShape,
    pub(crate) params: Vec<f32>,
    pub(crate) adam: Adam,
    pub(crate) obs_norm: RunningMeanStd,
    pub(crate) rng: Rng,
    pub(crate) counters: Counters,
    /// SPEC S8: a terrain specialist trains only on transitions it acted itself where the
    /// estimator said its terrain; `None` (the general model): on all. Set by the caller, not
    /// checkpointed: it is the role the learner plays in a run, not learned state.
    specialist: Option<PolicySlot>,
    /// Workers of a fused update (`ppo.threads` resolved for this run).
    threads: usize,
    train_device: Device,
    eval_device: Device,
}

/// The state a checkpoint carries besides the architecture.
pub(crate) struct LearnerState {
    pub params: Vec<f32>,
    pub adam: Adam,
    pub obs_norm: RunningMeanStd,
    pub rng: Rng,
    pub counters: Counters,
}

impl Learner {
    /// A fresh learner for `layout` (whose hidden widths must be `cfg.ppo.hidden`, obs and
    /// action sizes those of [`Transition`]), initialised from `seed`.
    pub fn new(cfg: &Config, layout: PolicyLayout, seed: u64) -> Result<Self, LearnerError> {
        let mut rng = Rng::new(seed);
        let shape = NetShape::new(&layout);
        let params = shape.init(cfg.ppo.ortho_init, cfg.ppo.init_log_std as f32, &mut rng);
        let adam = Adam::new(params.len(), cfg.ppo.adam_eps as f32);
        let state = LearnerState {
            params,
            adam,
            obs_norm: RunningMeanStd::new(layout.obs_dim),
            rng,
            counters: Counters::default(),
        };
        Self::from_state(cfg, layout, state)
    }

    /// A learner continuing from saved state under (possibly changed) hyperparameters `cfg`.
    pub(crate) fn from_state(
        cfg: &Config,
        layout: PolicyLayout,
        state: LearnerState,
    ) -> Result<Self, LearnerError> {
        let p = &cfg.ppo;
        if layout.obs_dim != OBS_DIM || layout.act_dim != ACT_DIM {
            return Err(LearnerError::setting(
                "layout",
                format!("needs {OBS_DIM} observations and {ACT_DIM} actions, got {layout:?}"),
            ));
        }
        if layout.hidden != p.hidden || p.hidden.is_empty() || p.hidden.contains(&0) {
            return Err(LearnerError::setting(
                "ppo.hidden",
                format!(
                    "{:?} must be non-empty, non-zero and match the layout's {:?}",
                    p.hidden, layout.hidden
                ),
            ));
        }
        if p.minibatch_size == 0 || p.epochs == 0 {
            return Err(LearnerError::setting(
                "ppo.minibatch-size",
                "minibatch size and epochs must be at least 1",
            ));
        }
        let shape = NetShape::new(&layout);
        let n = shape.len();
        if state.params.len() != n || state.adam.m.len() != n || state.adam.v.len() != n {
            return Err(LearnerError::setting(
                "params",
                format!(
                    "the layout needs {n} parameters, the state has {}",
                    state.params.len()
                ),
            ));
        }
        if state.obs_norm.dim() != OBS_DIM {
            return Err(LearnerError::setting(
                "obs-norm",
                format!("has {} features, not {OBS_DIM}", state.obs_norm.dim()),
            ));
        }
        let mut adam = state.adam;
        adam.eps = p.adam_eps as f32;
        let eval_device = Device::flex();
        Ok(Self {
            ppo: p.clone(),
            total_steps: cfg.run.total_steps,
            decision_dt: cfg.sim.decision_dt(),
            shape,
            params: state.params,
            adam,
            obs_norm: state.obs_norm,
            rng: state.rng,
            counters: state.counters,
            specialist: None,
            threads: p.update_threads(
                cfg.run.mode == LearnMode::Sync,
                cfg.sim.threads,
                cfg.run.learners.len(),
            ),
            train_device: eval_device.clone().autodiff(),
            eval_device,
        })
    }

    pub fn layout(&self) -> &PolicyLayout {
        &self.shape.layout
    }

    /// Worker threads of an update (1 on the burn engine).
    pub fn update_threads(&self) -> usize {
        match self.ppo.engine {
            PpoEngine::Fused => self.threads,
            PpoEngine::Burn => 1,
        }
    }

    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Makes this learner the one of `slot` (SPEC S8). A specialist trains only on the
    /// transitions whose estimator class is its terrain's and that its own policy acted: when
    /// switching holds the other specialist for a dwell time after the estimate changed,
    /// those transitions carry the other policy's log-probabilities, and PPO's ratio on them
    /// would be against the wrong behaviour policy. The general model trains on all.
    pub fn play(&mut self, slot: PolicySlot) {
        self.specialist = slot.class().map(|_| slot);
    }

    pub fn policy_version(&self) -> u32 {
        self.counters.policy_version
    }

    /// Whether the runtime should save a checkpoint now: every `checkpoint-every` updates.
    pub fn checkpoint_due(&self) -> bool {
        let every = self.ppo.checkpoint_every.max(1) as u64;
        self.counters.update > 0 && self.counters.update.is_multiple_of(every)
    }

    /// The actor in the `common::policy` flat layout: observation mean and variance, dense
    /// layers, log-std. What the `policy` service ships and `common::Policy` evaluates.
    pub fn policy_weights(&self) -> Vec<f32> {
        shipped_weights(&self.obs_norm, &self.shape, &self.params)
    }

    /// The learning rate the next update will use (SPEC S6: 3e-4, linear decay to 0 over
    /// `run.total-steps`, CleanRL's `frac = 1 − (iteration − 1) / num_iterations`).
    pub fn learning_rate(&self) -> f64 {
        if !self.ppo.anneal_lr {
            return self.ppo.learning_rate;
        }
        let frac = 1.0 - self.counters.global_step as f64 / self.total_steps.max(1) as f64;
        self.ppo.learning_rate * frac.max(0.0)
    }
}
