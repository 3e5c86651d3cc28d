//! PPO (SPEC S6), read top to bottom like CleanRL's `ppo_continuous_action.py`: value pass and
//! GAE over the rollout, then epochs of shuffled minibatches with the clipped surrogate,
//! optional value clipping, an entropy bonus, global gradient-norm clipping and Adam with a
//! linearly decaying learning rate.
//!
//! Observation normalisation: an update trains on the statistics the behaviour policy acted
//! with (the ones last shipped), so the first epoch's ratios start at 1; afterwards the
//! statistics absorb the rollout's observations and ship with the new weights.

use std::time::Instant;

use burn::tensor::{Device, Tensor, TensorData};
use common::config::{Config, PolicySlot, PpoConfig};
use common::policy::{PolicyLayout, sample_gaussian};
use common::{ACT_DIM, OBS_DIM, Rng, Transition};
use serde::{Deserialize, Serialize};

use crate::LearnerError;
use crate::adam::{Adam, clip_global_norm};
use crate::gae::{bootstrap_truncated, gae};
use crate::loss::{clipped_surrogate, gaussian_entropy, gaussian_logprob, value_loss};
use crate::metrics::{EpisodeOutcome, EpisodeSummary, UpdateMetrics};
use crate::net::{NetShape, read};
use crate::obs_norm::{RunningMeanStd, normalise};

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

/// An action drawn from the policy: unclipped (the simulator clips it) with its log-probability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampledAction {
    pub action: [f32; ACT_DIM],
    pub logprob: f32,
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
    train_device: Device,
    eval_device: Device,
}

/// The rollout flattened to `[batch, …]` host arrays (CleanRL's `b_*`).
struct Batch {
    b_obs: Vec<f32>,
    b_actions: Vec<f32>,
    b_logprobs: Vec<f32>,
    b_advantages: Vec<f32>,
    b_returns: Vec<f32>,
    b_values: Vec<f32>,
}

/// What one minibatch step reports (and, summed, what an update averages).
#[derive(Debug, Clone, Copy, Default)]
struct MinibatchStats {
    pg_loss: f64,
    v_loss: f64,
    entropy: f64,
    old_approx_kl: f64,
    approx_kl: f64,
    clipfrac: f64,
    grad_norm: f64,
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
            train_device: eval_device.clone().autodiff(),
            eval_device,
        })
    }

    pub fn layout(&self) -> &PolicyLayout {
        &self.shape.layout
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

    /// Network input rows: observations normalised with the shipped statistics, each followed
    /// by the constant 1 that carries the first layer's bias (`net` module), `[rows, IN]` flat.
    fn normalised(&self, obs: impl Iterator<Item = [f32; OBS_DIM]>) -> Vec<f32> {
        let (mean, var) = self.obs_norm.shipped();
        let mut x: Vec<f32> = obs.flat_map(|o| o.into_iter().chain([1.0])).collect();
        normalise(&mut x, IN, &mean, &var, self.ppo.obs_clip as f32);
        x
    }

    /// A `[rows, cols]` tensor on the inference device from a flat row-major buffer.
    fn eval_tensor(&self, data: Vec<f32>, cols: usize) -> Tensor<2> {
        let rows = data.len() / cols;
        Tensor::from_data(TensorData::new(data, [rows, cols]), &self.eval_device)
    }

    /// Action means for raw observations (the deterministic policy), via burn.
    pub fn mean_actions(
        &self,
        obs: &[[f32; OBS_DIM]],
    ) -> Result<Vec<[f32; ACT_DIM]>, LearnerError> {
        if obs.is_empty() {
            return Ok(Vec::new());
        }
        let x = self.normalised(obs.iter().copied());
        let net = self.shape.tensors(&self.params, &self.eval_device, false);
        let mean = read(net.actor_mean(self.eval_tensor(x, IN))?, "action mean")?;
        Ok(mean
            .chunks_exact(ACT_DIM)
            .map(|m| std::array::from_fn(|k| m[k]))
            .collect())
    }

    /// Samples unclipped actions for raw observations and returns them with their
    /// log-probabilities under the current policy, with the simulator's sampler
    /// ([`sample_gaussian`]). `rng` is the caller's (per env or runtime), so sampling never
    /// disturbs the learner's own stream.
    pub fn sample_actions(
        &self,
        obs: &[[f32; OBS_DIM]],
        rng: &mut Rng,
    ) -> Result<Vec<SampledAction>, LearnerError> {
        let log_std = &self.params[self.shape.blocks[self.shape.log_std_block()].range()];
        let means = self.mean_actions(obs)?;
        Ok(means
            .into_iter()
            .map(|mean| {
                let mut action = [0.0f32; ACT_DIM];
                let logprob = sample_gaussian(&mean, log_std, rng, &mut action);
                SampledAction { action, logprob }
            })
            .collect())
    }

    /// State values for raw observations.
    pub fn values(&self, obs: &[[f32; OBS_DIM]]) -> Result<Vec<f32>, LearnerError> {
        if obs.is_empty() {
            return Ok(Vec::new());
        }
        self.values_normalised(self.normalised(obs.iter().copied()))
    }

    fn values_normalised(&self, x: Vec<f32>) -> Result<Vec<f32>, LearnerError> {
        let net = self.shape.tensors(&self.params, &self.eval_device, false);
        read(net.value(self.eval_tensor(x, IN))?, "value")
    }

    /// One PPO update on `rollout`. On error (malformed rollout, non-finite loss or gradient)
    /// the learner is left exactly as it was.
    pub fn update(&mut self, rollout: &Rollout) -> Result<UpdateMetrics, LearnerError> {
        let started = Instant::now();
        let (steps, envs) = check_rollout(rollout)?;
        let batch_size = steps * envs;
        let transitions = rollout.transitions;

        // Values of every observation, each env's bootstrap observation, and the final
        // observation of every truncated step, in one critic pass.
        let cut_short: Vec<usize> = (0..batch_size)
            .filter(|&i| transitions[i].truncated != 0 && transitions[i].terminated == 0)
            .collect();
        let all_obs = transitions
            .iter()
            .map(|t| t.obs)
            .chain(rollout.bootstrap_obs.iter().copied())
            .chain(cut_short.iter().map(|&i| transitions[i].final_obs));
        let x = self.normalised(all_obs);
        let b_obs = x[..batch_size * IN].to_vec(); // [steps * envs, obs + 1]
        let all_values = self.values_normalised(x)?;
        let values = &all_values[..batch_size]; // [steps, envs]
        let next_value = &all_values[batch_size..batch_size + envs]; // [envs]
        let mut final_values = vec![0.0f32; batch_size];
        for (k, &i) in cut_short.iter().enumerate() {
            final_values[i] = all_values[batch_size + envs + k];
        }

        let gamma = self.ppo.gamma as f32;
        let mut rewards: Vec<f32> = transitions.iter().map(|t| t.reward).collect(); // [steps, envs]
        let terminated: Vec<bool> = transitions.iter().map(|t| t.terminated != 0).collect();
        let truncated: Vec<bool> = transitions.iter().map(|t| t.truncated != 0).collect();
        bootstrap_truncated(&mut rewards, &terminated, &truncated, &final_values, gamma);
        let ended: Vec<bool> = terminated
            .iter()
            .zip(&truncated)
            .map(|(a, b)| *a || *b)
            .collect();
        let g = gae(
            &rewards,
            values,
            &ended,
            next_value,
            gamma,
            self.ppo.gae_lambda as f32,
        );

        let batch = Batch {
            b_obs,
            b_actions: transitions.iter().flat_map(|t| t.action).collect(),
            b_logprobs: transitions.iter().map(|t| t.logprob).collect(),
            b_advantages: g.advantages,
            b_returns: g.returns,
            b_values: values.to_vec(),
        };

        // Optimise policy and value networks. Work on copies so a failure leaves no trace.
        let lr = self.learning_rate() as f32;
        let mut params = self.params.clone();
        let mut adam = self.adam.clone();
        let mut rng = self.rng.clone();
        // Async mode (DESIGN §3): transitions acted by a policy more than `max-policy-lag`
        // versions old still shape the advantages of their neighbours but are not trained on.
        let version = self.counters.policy_version;
        let lag = |t: &Transition| version.saturating_sub(t.policy_version);
        let fresh: Vec<usize> = (0..batch_size)
            .filter(|&i| lag(&transitions[i]) <= self.ppo.max_policy_lag)
            .collect();
        let stale = batch_size - fresh.len();
        // SPEC S8: a specialist's other-terrain and other-policy transitions likewise only
        // shape advantages.
        let mut b_inds: Vec<usize> = fresh
            .into_iter()
            .filter(|&i| {
                let t = &transitions[i];
                self.specialist.is_none_or(|s| {
                    usize::from(t.slot) == s.index() && s.class() == Some(t.estimated_class)
                })
            })
            .collect();
        if b_inds.is_empty() {
            return Err(LearnerError::rollout(format!(
                "none of {batch_size} transitions to train on: {stale} more than {} policy versions old, the rest of other terrain classes or acted by another policy",
                self.ppo.max_policy_lag
            )));
        }
        let minibatch_size = self.ppo.minibatch_size.min(b_inds.len());
        // Full minibatches only (as ML-Agents); the remainder differs per epoch's shuffle.
        let num_minibatches = b_inds.len() / minibatch_size;
        let mut grads = vec![0.0f32; params.len()];
        let mut sums = MinibatchStats::default();
        let mut epochs_run = 0;
        let mut approx_kl = 0.0;
        for _epoch in 0..self.ppo.epochs {
            rng.shuffle(&mut b_inds);
            for start in (0..num_minibatches).map(|k| k * minibatch_size) {
                let mb_inds = &b_inds[start..start + minibatch_size];
                let stats =
                    self.minibatch_step(&batch, mb_inds, &mut params, &mut adam, &mut grads, lr)?;
                sums.add(&stats);
                approx_kl = stats.approx_kl;
            }
            epochs_run += 1;
            // CleanRL's early stop looks at the epoch's last minibatch.
            if self.ppo.target_kl.is_some_and(|kl| approx_kl > kl) {
                break;
            }
        }
        let n_mb = (epochs_run * num_minibatches) as f64;

        let explained_var = explained_variance(&batch.b_values, &batch.b_returns);
        let mean_lag =
            transitions.iter().map(|t| f64::from(lag(t))).sum::<f64>() / batch_size as f64;

        self.params = params;
        self.adam = adam;
        self.rng = rng;
        if self.ppo.obs_norm {
            self.obs_norm
                .update(transitions.iter().map(|t| t.obs.as_slice()));
        }
        self.counters.update += 1;
        self.counters.global_step += batch_size as u64;
        self.counters.policy_version += 1;

        let samples = (epochs_run * num_minibatches * minibatch_size) as f64;
        let episodes = EpisodeSummary::of(rollout.episodes, self.decision_dt);
        let metrics = UpdateMetrics {
            update: self.counters.update,
            global_step: self.counters.global_step,
            policy_version: self.counters.policy_version,
            learning_rate: f64::from(lr),
            policy_loss: sums.pg_loss / n_mb,
            value_loss: sums.v_loss / n_mb,
            entropy: sums.entropy / n_mb,
            old_approx_kl: sums.old_approx_kl / n_mb,
            approx_kl: sums.approx_kl / n_mb,
            clip_fraction: sums.clipfrac / n_mb,
            explained_variance: explained_var,
            grad_norm: sums.grad_norm / n_mb,
            epochs: epochs_run,
            samples_per_second: samples / started.elapsed().as_secs_f64(),
            mean_policy_lag: mean_lag,
            stale_transitions: stale,
            episodes: episodes.count,
            mean_episode_return: episodes.mean_return,
            success_rate: episodes.success_rate,
            mean_reach_time_s: episodes.mean_reach_time_s,
        };
        tracing::debug!(
            update = metrics.update,
            policy_loss = metrics.policy_loss,
            value_loss = metrics.value_loss,
            approx_kl = metrics.approx_kl,
            "ppo update"
        );
        Ok(metrics)
    }

    /// Forward, backward and one optimizer step on the minibatch `mb_inds`.
    fn minibatch_step(
        &self,
        batch: &Batch,
        mb_inds: &[usize],
        params: &mut [f32],
        adam: &mut Adam,
        grads: &mut [f32],
        lr: f32,
    ) -> Result<MinibatchStats, LearnerError> {
        let device = &self.train_device;
        let mb = mb_inds.len();
        let gather = |src: &[f32], width: usize| -> Vec<f32> {
            let mut out = Vec::with_capacity(mb * width);
            for &i in mb_inds {
                out.extend_from_slice(&src[i * width..(i + 1) * width]);
            }
            out
        };
        let tensor = |data: Vec<f32>, width: usize| {
            Tensor::<2>::from_data(TensorData::new(data, [mb, width]), device)
        };

        let mut mb_advantages = gather(&batch.b_advantages, 1);
        if self.ppo.norm_adv {
            normalise_advantages(&mut mb_advantages);
        }
        let net = self.shape.tensors(params, device, true);
        let obs = tensor(gather(&batch.b_obs, IN), IN); // [mb, obs + 1]
        let log_std = net.log_std(); // [1, act]
        let newlogprob = gaussian_logprob(
            net.actor_mean(obs.clone())?,
            log_std.clone(),
            tensor(gather(&batch.b_actions, ACT_DIM), ACT_DIM),
        ); // [mb, 1]
        let entropy = gaussian_entropy(log_std); // [1, 1]
        let logratio = newlogprob - tensor(gather(&batch.b_logprobs, 1), 1);
        let ratio = logratio.clone().exp();

        let (old_approx_kl, approx_kl, clipfrac) =
            kl_and_clipfrac(&read(logratio, "log-ratio")?, self.ppo.clip_coef);

        let pg_loss = clipped_surrogate(ratio, tensor(mb_advantages, 1), self.ppo.clip_coef as f32);
        let newvalue = net.value(obs)?; // [mb, 1]
        let v_loss = value_loss(
            newvalue,
            tensor(gather(&batch.b_values, 1), 1),
            tensor(gather(&batch.b_returns, 1), 1),
            self.ppo.clip_vloss.then_some(self.ppo.clip_coef as f32),
        );
        let entropy_loss = entropy.mean();
        let loss = pg_loss.clone() - entropy_loss.clone().mul_scalar(self.ppo.ent_coef)
            + v_loss.clone().mul_scalar(self.ppo.vf_coef);

        let backward = loss.backward();
        self.shape.gradients(&net, &backward, grads)?;
        let grad_norm = clip_global_norm(grads, self.ppo.max_grad_norm as f32);
        let stats = MinibatchStats {
            pg_loss: first(read(pg_loss, "policy loss")?),
            v_loss: first(read(v_loss, "value loss")?),
            entropy: first(read(entropy_loss, "entropy")?),
            old_approx_kl,
            approx_kl,
            clipfrac,
            grad_norm: f64::from(grad_norm),
        };
        if !(stats.pg_loss.is_finite() && stats.v_loss.is_finite() && stats.grad_norm.is_finite()) {
            return Err(LearnerError::NonFinite {
                update: self.counters.update + 1,
                what: "loss or gradient",
            });
        }
        adam.step(params, grads, lr);
        Ok(stats)
    }
}

/// The state a checkpoint carries besides the architecture.
pub(crate) struct LearnerState {
    pub params: Vec<f32>,
    pub adam: Adam,
    pub obs_norm: RunningMeanStd,
    pub rng: Rng,
    pub counters: Counters,
}

impl MinibatchStats {
    fn add(&mut self, o: &Self) {
        self.pg_loss += o.pg_loss;
        self.v_loss += o.v_loss;
        self.entropy += o.entropy;
        self.old_approx_kl += o.old_approx_kl;
        self.approx_kl += o.approx_kl;
        self.clipfrac += o.clipfrac;
        self.grad_norm += o.grad_norm;
    }
}

/// The value of a one-element tensor read back to the host.
fn first(v: Vec<f32>) -> f64 {
    v.first().map_or(f64::NAN, |&x| f64::from(x))
}

/// Checks the rollout's shape; returns `(steps, envs)`.
fn check_rollout(rollout: &Rollout) -> Result<(usize, usize), LearnerError> {
    let envs = rollout.bootstrap_obs.len();
    let n = rollout.transitions.len();
    if envs == 0 || n == 0 || !n.is_multiple_of(envs) {
        return Err(LearnerError::rollout(format!(
            "{n} transitions do not form whole rows of {envs} envs"
        )));
    }
    let first_row = &rollout.transitions[..envs];
    if let Some((i, t)) = rollout
        .transitions
        .iter()
        .enumerate()
        .find(|(i, t)| t.env != first_row[i % envs].env)
    {
        return Err(LearnerError::rollout(format!(
            "transition {i} (step {}, slot {}) is env {} but the first row has env {} there",
            i / envs,
            i % envs,
            t.env,
            first_row[i % envs].env
        )));
    }
    if let Some(i) = rollout.transitions.iter().position(|t| {
        !(t.obs.iter().chain(&t.action).all(|x| x.is_finite())
            && t.reward.is_finite()
            && t.logprob.is_finite())
    }) {
        return Err(LearnerError::rollout(format!(
            "transition {i} has a non-finite value"
        )));
    }
    Ok((n / envs, envs))
}

/// Per-minibatch advantage normalisation (SPEC S6): zero mean, unit (sample) std.
/// A single sample has no spread and is left alone.
fn normalise_advantages(adv: &mut [f32]) {
    let n = adv.len();
    if n < 2 {
        return;
    }
    let mean = adv.iter().map(|&a| f64::from(a)).sum::<f64>() / n as f64;
    let var = adv
        .iter()
        .map(|&a| (f64::from(a) - mean).powi(2))
        .sum::<f64>()
        / (n - 1) as f64;
    let std = var.sqrt();
    adv.iter_mut()
        .for_each(|a| *a = ((f64::from(*a) - mean) / (std + 1e-8)) as f32);
}

/// CleanRL's diagnostics from `logratio = log π_new − log π_old`: old approx KL `mean(−logratio)`,
/// approx KL `mean((r − 1) − logratio)` (Schulman's k3), and the fraction with `|r − 1| > ε`.
fn kl_and_clipfrac(logratio: &[f32], clip_coef: f64) -> (f64, f64, f64) {
    let n = logratio.len().max(1) as f64;
    let (mut old_kl, mut kl, mut clipped) = (0.0, 0.0, 0.0);
    for &lr in logratio {
        let lr = f64::from(lr);
        let ratio = lr.exp();
        old_kl -= lr;
        kl += (ratio - 1.0) - lr;
        if (ratio - 1.0).abs() > clip_coef {
            clipped += 1.0;
        }
    }
    (old_kl / n, kl / n, clipped / n)
}

/// `1 − Var(returns − values) / Var(returns)` (population variances); NaN when the returns
/// do not vary.
fn explained_variance(values: &[f32], returns: &[f32]) -> f64 {
    let var = |xs: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = xs.collect();
        let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
        v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len().max(1) as f64
    };
    let var_y = var(&mut returns.iter().map(|&r| f64::from(r)));
    if var_y == 0.0 {
        return f64::NAN;
    }
    1.0 - var(&mut returns
        .iter()
        .zip(values)
        .map(|(&r, &v)| f64::from(r) - f64::from(v)))
        / var_y
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use common::Policy;

    /// A small config: 64-64 networks, `steps × envs` rollouts, LR decay over `updates` of them.
    pub(crate) fn small_config(minibatch: usize, updates: u64) -> Config {
        let mut cfg = Config::default();
        cfg.ppo.hidden = vec![64, 64];
        cfg.ppo.minibatch_size = minibatch;
        cfg.ppo.epochs = 2;
        cfg.run.total_steps = updates * 64 * 4;
        cfg
    }

    pub(crate) fn learner(cfg: &Config, seed: u64) -> Learner {
        Learner::new(
            cfg,
            PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM),
            seed,
        )
        .expect("learner")
    }

    /// An owned rollout of `steps × envs` transitions acted by `learner`'s current policy, with
    /// random rewards and some terminations and truncations.
    pub(crate) struct OwnedRollout {
        pub transitions: Vec<Transition>,
        pub bootstrap: Vec<[f32; OBS_DIM]>,
    }

    impl OwnedRollout {
        pub(crate) fn acted_by(learner: &Learner, steps: usize, envs: usize, seed: u64) -> Self {
            let mut rng = Rng::new(seed);
            let mut obs = || -> [f32; OBS_DIM] {
                std::array::from_fn(|k| (k as f64 + 2.0 * rng.normal()) as f32)
            };
            let all: Vec<[f32; OBS_DIM]> = (0..steps * envs).map(|_| obs()).collect();
            let bootstrap = (0..envs).map(|_| obs()).collect();
            let finals: Vec<[f32; OBS_DIM]> = (0..steps * envs).map(|_| obs()).collect();
            let mut rng = Rng::new(seed + 1);
            let sampled = learner.sample_actions(&all, &mut rng).expect("sample");
            let transitions = all
                .iter()
                .zip(sampled)
                .enumerate()
                .map(|(i, (o, s))| Transition {
                    obs: *o,
                    action: s.action,
                    final_obs: finals[i],
                    logprob: s.logprob,
                    reward: rng.normal() as f32,
                    policy_version: learner.policy_version(),
                    env: (i % envs) as u32,
                    terminated: u8::from(rng.uniform() < 0.05),
                    truncated: u8::from(rng.uniform() < 0.05),
                    ..Transition::default()
                })
                .collect();
            Self {
                transitions,
                bootstrap,
            }
        }

        pub(crate) fn view(&self) -> Rollout<'_> {
            Rollout {
                transitions: &self.transitions,
                bootstrap_obs: &self.bootstrap,
                episodes: &[],
            }
        }
    }

    /// burn's actor forward on random weights, random normalisation statistics and inputs that
    /// hit the observation clip agrees with `common::Policy` on the shipped flat vector.
    #[test]
    fn burn_actor_matches_common_policy() {
        let mut cfg = Config::default();
        cfg.ppo.obs_clip = 3.0;
        let mut learner = learner(&cfg, 1);
        let mut rng = Rng::new(2);
        for block in &learner.shape.blocks {
            let scale = 1.5 / (block.rows as f64).sqrt();
            learner.params[block.range()]
                .iter_mut()
                .for_each(|p| *p = (scale * rng.normal()) as f32);
        }
        learner
            .obs_norm
            .mean
            .iter_mut()
            .for_each(|m| *m = rng.normal());
        learner
            .obs_norm
            .var
            .iter_mut()
            .for_each(|v| *v = rng.range(0.01, 4.0));
        let obs: Vec<[f32; OBS_DIM]> = (0..64)
            .map(|_| std::array::from_fn(|_| (3.0 * rng.normal()) as f32))
            .collect();

        let burn_means = learner.mean_actions(&obs).expect("burn forward");
        let mut policy =
            Policy::new(learner.layout().clone(), learner.policy_weights(), 3.0).expect("layout");
        let mut worst = 0.0f32;
        for (o, b) in obs.iter().zip(&burn_means) {
            let mut m = [0.0; ACT_DIM];
            policy.mean_action(o, &mut m);
            for k in 0..ACT_DIM {
                worst = worst.max((m[k] - b[k]).abs());
            }
        }
        assert!(worst < 1e-5, "max difference {worst}");
        assert!(
            burn_means.iter().any(|m| m[0].abs() > 0.1),
            "a trivial network proves nothing"
        );
        assert_eq!(
            policy.log_std(),
            &learner.params[learner.shape.blocks[learner.shape.log_std_block()].range()]
        );
    }

    /// The flat vector is obs mean, obs var, then the actor's blocks exactly as the learner holds them.
    #[test]
    fn policy_weights_round_trip_through_the_layout() {
        let mut learner = learner(&Config::default(), 3);
        learner.obs_norm.update(
            [[0.5f32; OBS_DIM], [1.5; OBS_DIM]]
                .iter()
                .map(|r| r.as_slice()),
        );
        let w = learner.policy_weights();
        let layout = learner.layout().clone();
        assert_eq!(w.len(), layout.len());
        let (mean, var) = learner.obs_norm.shipped();
        assert_eq!(&w[layout.obs_mean()..layout.obs_var()], mean.as_slice());
        assert_eq!(&w[layout.obs_var()..2 * OBS_DIM], var.as_slice());
        for (l, dense) in layout.dense_layers().iter().enumerate() {
            let (ws, bs) = (learner.shape.blocks[2 * l], learner.shape.blocks[2 * l + 1]);
            assert_eq!(&w[dense.weight..dense.bias], &learner.params[ws.range()]);
            assert_eq!(
                &w[dense.bias..dense.bias + dense.outputs],
                &learner.params[bs.range()]
            );
        }
        assert_eq!(
            &w[layout.log_std()..],
            &learner.params[learner.shape.blocks[learner.shape.log_std_block()].range()]
        );
    }

    /// Sampled log-probabilities agree with burn's: a one-minibatch, one-epoch update on the
    /// policy's own actions starts (and, with one step, measures) at ratio 1.
    #[test]
    fn behaviour_logprobs_match_so_the_first_ratio_is_one() {
        let mut cfg = small_config(256, 10);
        cfg.ppo.epochs = 1;
        let mut learner = learner(&cfg, 4);
        let rollout = OwnedRollout::acted_by(&learner, 64, 4, 5);
        let m = learner.update(&rollout.view()).expect("update");
        assert!(
            m.approx_kl.abs() < 1e-6 && m.old_approx_kl.abs() < 1e-5,
            "{m:?}"
        );
        assert_eq!(m.clip_fraction, 0.0);
        assert_eq!(
            (m.update, m.global_step, m.policy_version, m.epochs),
            (1, 256, 1, 1)
        );
        assert!(m.value_loss > 0.0 && m.entropy > 2.0 && m.grad_norm > 0.0);
    }

    /// SPEC S6: 3e-4 decaying linearly to 0 over the run; constant when annealing is off.
    /// Also: a checkpoint is due every `checkpoint-every` updates.
    #[test]
    fn learning_rate_decays_linearly_per_update() {
        let mut cfg = small_config(128, 4); // 4 updates of 256 transitions
        cfg.ppo.checkpoint_every = 2;
        let mut learner = learner(&cfg, 6);
        assert!(!learner.checkpoint_due());
        let rollout = OwnedRollout::acted_by(&learner, 64, 4, 7);
        let mut due = Vec::new();
        let mut lrs = Vec::new();
        for _ in 0..5 {
            lrs.push(
                learner
                    .update(&rollout.view())
                    .expect("update")
                    .learning_rate,
            );
            due.push(learner.checkpoint_due());
        }
        assert_eq!(due, [false, true, false, true, false]);
        for (got, want) in lrs.iter().zip([3e-4, 2.25e-4, 1.5e-4, 0.75e-4, 0.0]) {
            assert!((got - want).abs() < 1e-9, "{lrs:?}");
        }
        cfg.ppo.anneal_lr = false;
        let mut flat = Learner::new(&cfg, learner.layout().clone(), 6).expect("learner");
        flat.update(&rollout.view()).expect("update");
        assert_eq!(flat.learning_rate(), 3e-4);
    }

    #[test]
    fn malformed_rollouts_are_refused_without_side_effects() {
        let mut learner = learner(&small_config(64, 10), 8);
        let good = OwnedRollout::acted_by(&learner, 16, 4, 9);
        let before = learner.policy_weights();

        let short = Rollout {
            transitions: &good.transitions[..63],
            ..good.view()
        };
        let e = learner
            .update(&short)
            .expect_err("63 is not a multiple of 4");
        assert!(e.to_string().contains("63 transitions"), "{e}");

        let mut shuffled = good.transitions.clone();
        shuffled.swap(5, 6);
        let e = learner
            .update(&Rollout {
                transitions: &shuffled,
                ..good.view()
            })
            .expect_err("env order changes between rows");
        assert!(e.to_string().contains("transition 5"), "{e}");

        let mut nan = good.transitions.clone();
        nan[10].reward = f32::NAN;
        assert!(
            learner
                .update(&Rollout {
                    transitions: &nan,
                    ..good.view()
                })
                .is_err()
        );

        assert_eq!(learner.policy_weights(), before);
        assert_eq!(learner.counters(), Counters::default());
    }

    /// SPEC S8: a specialist trains only on its terrain class's transitions that it acted;
    /// a chunk with none of them changes nothing.
    #[test]
    fn a_specialist_trains_only_on_its_terrain_class() {
        let cfg = small_config(64, 10);
        let mut flat = learner(&cfg, 10);
        flat.play(PolicySlot::Flat);
        let mut rollout = OwnedRollout::acted_by(&flat, 16, 4, 11);
        rollout.transitions.iter_mut().for_each(|t| {
            t.estimated_class = 1;
            t.slot = PolicySlot::Flat.index() as u8;
        });
        let before = flat.policy_weights();
        let e = flat
            .update(&rollout.view())
            .expect_err("no flat transitions");
        assert!(e.to_string().contains("other terrain classes"), "{e}");
        assert_eq!(flat.policy_weights(), before, "left unchanged");
        // Flat ground by the estimate, but acted by the rough-terrain model (switching's dwell).
        rollout.transitions[..16].iter_mut().for_each(|t| {
            t.estimated_class = 0;
            t.slot = PolicySlot::Rough.index() as u8;
        });
        flat.update(&rollout.view())
            .expect_err("no flat transitions of its own");
        assert_eq!(flat.policy_weights(), before, "left unchanged");
        rollout.transitions[..16]
            .iter_mut()
            .for_each(|t| t.slot = PolicySlot::Flat.index() as u8);
        flat.update(&rollout.view()).expect("16 flat transitions");
        assert_ne!(flat.policy_weights(), before);
    }

    /// Async mode: transitions older than `max-policy-lag` versions are not trained on.
    #[test]
    fn stale_transitions_are_dropped_and_counted() {
        let mut cfg = small_config(64, 10);
        cfg.ppo.max_policy_lag = 1;
        let mut learner = learner(&cfg, 10);
        let mut rollout = OwnedRollout::acted_by(&learner, 16, 4, 11);
        learner.update(&rollout.view()).expect("version 0 -> 1");
        learner.update(&rollout.view()).expect("version 1 -> 2");
        // Rows 0..8 were acted by version 0 (lag 2), the rest by version 2.
        for (i, t) in rollout.transitions.iter_mut().enumerate() {
            t.policy_version = if i < 32 { 0 } else { 2 };
        }
        let m = learner.update(&rollout.view()).expect("update");
        assert_eq!((m.stale_transitions, m.mean_policy_lag), (32, 1.0));
        assert_eq!(m.global_step, 3 * 64);
        rollout
            .transitions
            .iter_mut()
            .for_each(|t| t.policy_version = 0);
        let e = learner.update(&rollout.view()).expect_err("all stale");
        assert!(
            e.to_string().contains("more than 1 policy versions old"),
            "{e}"
        );
    }

    #[test]
    fn learner_can_move_to_another_thread() {
        fn send<T: Send>() {}
        send::<Learner>();
    }

    #[test]
    fn advantage_normalisation_and_diagnostics_by_hand() {
        let mut adv = [1.0f32, 2.0, 3.0];
        normalise_advantages(&mut adv); // mean 2, sample std 1
        assert!((adv[0] + 1.0).abs() < 1e-6 && adv[1].abs() < 1e-6 && (adv[2] - 1.0).abs() < 1e-6);
        let mut one = [5.0f32];
        normalise_advantages(&mut one);
        assert_eq!(one, [5.0]);

        // logratio 0 and ln 1.5: ratios 1 and 1.5.
        let (old_kl, kl, clipfrac) = kl_and_clipfrac(&[0.0, 1.5f32.ln()], 0.2);
        assert!((old_kl + 0.5 * 1.5f64.ln()).abs() < 1e-7);
        assert!((kl - 0.5 * (0.5 - 1.5f64.ln())).abs() < 1e-7);
        assert_eq!(clipfrac, 0.5);

        // returns 1, 2, 3 and values 1, 2, 2: 1 − Var(0, 0, 1)/Var(1, 2, 3) = 1 − (2/9)/(2/3) = 2/3.
        assert!((explained_variance(&[1.0, 2.0, 2.0], &[1.0, 2.0, 3.0]) - 2.0 / 3.0).abs() < 1e-12);
        assert!(explained_variance(&[0.0, 1.0], &[1.0, 1.0]).is_nan());
    }
}
