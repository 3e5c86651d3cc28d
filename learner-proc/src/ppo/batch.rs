//! From a rollout to what PPO trains on: the shape checks, one critic pass, GAE with
//! truncation bootstrapping (CleanRL's "bootstrap value if not done"), the flattened `b_*`
//! arrays ("flatten the batch"), and the `b_inds` an update may draw its minibatches from.

use common::Transition;
use common::config::PpoEngine;

use super::{IN, Learner, Rollout};
use crate::LearnerError;
use crate::gae::{bootstrap_truncated, gae};

/// The rollout flattened to `[batch, …]` host arrays (CleanRL's `b_*`).
pub(super) struct Batch {
    /// Normalised observations with the bias unit, `[batch, obs + 1]`.
    pub b_obs: Vec<f32>,
    pub b_actions: Vec<f32>,
    pub b_logprobs: Vec<f32>,
    pub b_advantages: Vec<f32>,
    pub b_returns: Vec<f32>,
    pub b_values: Vec<f32>,
}

/// Checks the rollout's shape; returns `(steps, envs)`.
pub(super) fn check_rollout(rollout: &Rollout) -> Result<(usize, usize), LearnerError> {
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

impl Learner {
    /// Advantages and returns of a checked `[steps, envs]` rollout, flattened with its
    /// observations, actions, log-probabilities and values.
    pub(super) fn batch(&self, rollout: &Rollout, envs: usize) -> Result<Batch, LearnerError> {
        let transitions = rollout.transitions;
        let batch_size = transitions.len();

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
        let all_values = match self.ppo.engine {
            PpoEngine::Fused => self.values_fused(&x),
            PpoEngine::Burn => self.values_normalised(x)?,
        };
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

        Ok(Batch {
            b_obs,
            b_actions: transitions.iter().flat_map(|t| t.action).collect(),
            b_logprobs: transitions.iter().map(|t| t.logprob).collect(),
            b_advantages: g.advantages,
            b_returns: g.returns,
            b_values: values.to_vec(),
        })
    }

    /// How many versions behind the current policy the one that acted `t` was.
    pub(super) fn policy_lag(&self, t: &Transition) -> u32 {
        self.counters
            .policy_version
            .saturating_sub(t.policy_version)
    }

    /// The indices of the transitions to train on (`b_inds`), and how many were left out as
    /// stale. The others still shaped their neighbours' advantages.
    pub(super) fn train_indices(
        &self,
        transitions: &[Transition],
    ) -> Result<(Vec<usize>, usize), LearnerError> {
        let batch_size = transitions.len();
        // Async mode (DESIGN §3): transitions acted by a policy more than `max-policy-lag`
        // versions old are not trained on.
        let fresh: Vec<usize> = (0..batch_size)
            .filter(|&i| self.policy_lag(&transitions[i]) <= self.ppo.max_policy_lag)
            .collect();
        let stale = batch_size - fresh.len();
        // SPEC S8: nor are a specialist's other-terrain and other-policy transitions.
        let b_inds: Vec<usize> = fresh
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
        Ok((b_inds, stale))
    }
}
