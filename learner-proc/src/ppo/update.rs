//! One PPO update, CleanRL's "optimizing the policy and value network": the batch, epochs of
//! shuffled minibatches with an optional early stop on the approximate KL (on burn's
//! autodiff, or on the fused engine of [`super::fused`], as `ppo.engine` says), then the
//! explained variance and the update's metrics.

use std::time::Instant;

use common::Rng;
use common::config::PpoEngine;

use super::batch::{Batch, check_rollout};
use super::minibatch::MinibatchStats;
use super::{Learner, Rollout};
use crate::LearnerError;
use crate::adam::Adam;
use crate::metrics::{EpisodeSummary, UpdateMetrics};

impl Learner {
    /// One PPO update on `rollout`. On error (malformed rollout, non-finite loss or gradient)
    /// the learner is left exactly as it was.
    pub fn update(&mut self, rollout: &Rollout) -> Result<UpdateMetrics, LearnerError> {
        let started = Instant::now();
        let (steps, envs) = check_rollout(rollout)?;
        let batch_size = steps * envs;
        let transitions = rollout.transitions;
        let batch = self.batch(rollout, envs)?;
        let (b_inds, stale) = self.train_indices(transitions)?;

        // Optimise policy and value networks, on copies so a failure leaves no trace.
        let lr = self.learning_rate() as f32;
        let minibatch_size = self.ppo.minibatch_size.min(b_inds.len());
        // Full minibatches only (as ML-Agents); the remainder differs per epoch's shuffle.
        let num_minibatches = b_inds.len() / minibatch_size;
        let Optimised {
            params,
            adam,
            rng,
            sums,
            epochs_run,
        } = match self.ppo.engine {
            PpoEngine::Fused => self.optimise_fused(&batch, b_inds, lr)?,
            PpoEngine::Burn => self.optimise_burn(&batch, b_inds, lr)?,
        };
        let n_mb = (epochs_run * num_minibatches) as f64;

        let explained_var = explained_variance(&batch.b_values, &batch.b_returns);
        let mean_lag = transitions
            .iter()
            .map(|t| f64::from(self.policy_lag(t)))
            .sum::<f64>()
            / batch_size as f64;

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
            // The serving loop knows the sources; an update alone does not.
            chunks_by_source: String::new(),
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
}

/// What an update's epochs leave: the new parameters, optimizer state and RNG, the sums of
/// the minibatches' statistics, and how many epochs ran.
pub(super) struct Optimised {
    pub params: Vec<f32>,
    pub adam: Adam,
    pub rng: Rng,
    pub sums: MinibatchStats,
    pub epochs_run: usize,
}

impl Learner {
    /// The epochs of one update on burn's autodiff, one minibatch at a time.
    fn optimise_burn(
        &self,
        batch: &Batch,
        mut b_inds: Vec<usize>,
        lr: f32,
    ) -> Result<Optimised, LearnerError> {
        let mut params = self.params.clone();
        let mut adam = self.adam.clone();
        let mut rng = self.rng.clone();
        let minibatch_size = self.ppo.minibatch_size.min(b_inds.len());
        let num_minibatches = b_inds.len() / minibatch_size;
        let mut grads = vec![0.0f32; params.len()];
        let mut sums = MinibatchStats::default();
        let mut epochs_run = 0;
        for _epoch in 0..self.ppo.epochs {
            rng.shuffle(&mut b_inds);
            let mut approx_kl = 0.0;
            for start in (0..num_minibatches).map(|k| k * minibatch_size) {
                let mb_inds = &b_inds[start..start + minibatch_size];
                let stats =
                    self.minibatch_step(batch, mb_inds, &mut params, &mut adam, &mut grads, lr)?;
                sums.add(&stats);
                approx_kl = stats.approx_kl;
            }
            epochs_run += 1;
            // CleanRL's early stop looks at the epoch's last minibatch.
            if self.ppo.target_kl.is_some_and(|kl| approx_kl > kl) {
                break;
            }
        }
        Ok(Optimised {
            params,
            adam,
            rng,
            sums,
            epochs_run,
        })
    }
}

/// `1 − Var(returns − values) / Var(returns)` (population variances); NaN when the returns
/// do not vary.
pub(super) fn explained_variance(values: &[f32], returns: &[f32]) -> f64 {
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
