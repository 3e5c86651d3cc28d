//! The learner's own forward passes on the inference device: the policy's mean and sampled
//! actions and the critic's values, for raw observations normalised with the shipped
//! statistics.

use burn::tensor::{Tensor, TensorData};
use common::policy::sample_gaussian;
use common::{ACT_DIM, OBS_DIM, Rng};

use super::{IN, Learner};
use crate::LearnerError;
use crate::net::read;
use crate::obs_norm::normalise;

/// An action drawn from the policy: unclipped (the simulator clips it) with its log-probability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampledAction {
    pub action: [f32; ACT_DIM],
    pub logprob: f32,
}

impl Learner {
    /// Network input rows: observations normalised with the shipped statistics, each followed
    /// by the constant 1 that carries the first layer's bias (`net` module), `[rows, IN]` flat.
    pub(super) fn normalised(&self, obs: impl Iterator<Item = [f32; OBS_DIM]>) -> Vec<f32> {
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

    pub(super) fn values_normalised(&self, x: Vec<f32>) -> Result<Vec<f32>, LearnerError> {
        let net = self.shape.tensors(&self.params, &self.eval_device, false);
        read(net.value(self.eval_tensor(x, IN))?, "value")
    }
}
