//! One minibatch step, as in CleanRL's inner loop: new log-probabilities and values for
//! `mb_inds`, the clipped surrogate, the (optionally clipped) value loss and the entropy
//! bonus, backward, global gradient-norm clipping and an Adam step.

use burn::tensor::{Tensor, TensorData};
use common::ACT_DIM;

use super::batch::Batch;
use super::{IN, Learner};
use crate::LearnerError;
use crate::adam::{Adam, clip_global_norm};
use crate::loss::{clipped_surrogate, gaussian_entropy, gaussian_logprob, value_loss};
use crate::net::read;

/// What one minibatch step reports (and, summed, what an update averages).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct MinibatchStats {
    pub pg_loss: f64,
    pub v_loss: f64,
    pub entropy: f64,
    pub old_approx_kl: f64,
    pub approx_kl: f64,
    pub clipfrac: f64,
    pub grad_norm: f64,
}

impl MinibatchStats {
    pub(super) fn add(&mut self, o: &Self) {
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

impl Learner {
    /// Forward, backward and one optimizer step on the minibatch `mb_inds`.
    pub(super) fn minibatch_step(
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

/// Per-minibatch advantage normalisation (SPEC S6): zero mean, unit (sample) std.
/// A single sample has no spread and is left alone.
pub(super) fn normalise_advantages(adv: &mut [f32]) {
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
pub(super) fn kl_and_clipfrac(logratio: &[f32], clip_coef: f64) -> (f64, f64, f64) {
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
