//! One item of a minibatch (the actor's or the critic's pass over one shard of its rows) and
//! the buffers a worker computes items in.

use common::{ACT_DIM, OBS_DIM};

use super::head::{HeadSettings, ShardRows, ShardSums, policy_head, value_head};
use super::mlp::Activations;
use super::plan::Net;
use super::shared::{ItemOut, Shared};
use crate::ppo::IN;
use crate::ppo::minibatch::normalise_advantages;

/// One worker's buffers, allocated once per update for a shard's rows.
pub(super) struct Workspace {
    x: Vec<f32>,
    actions: Vec<f32>,
    logprobs: Vec<f32>,
    values: Vec<f32>,
    returns: Vec<f32>,
    /// The whole minibatch's advantages, normalised.
    advantages: Vec<f32>,
    /// Each network's activations, indexed by [`Net`].
    acts: [Activations; 2],
    /// The loss's gradient with respect to the network's outputs.
    d_out: Vec<f32>,
}

impl Workspace {
    pub(super) fn new(shared: &Shared, rows: usize) -> Self {
        Self {
            x: Vec::with_capacity(rows * OBS_DIM),
            actions: Vec::with_capacity(rows * ACT_DIM),
            logprobs: Vec::with_capacity(rows),
            values: Vec::with_capacity(rows),
            returns: Vec::with_capacity(rows),
            advantages: Vec::with_capacity(shared.minibatch),
            acts: shared.nets.each_ref().map(|net| net.buffers(rows)),
            d_out: vec![0.0; rows * ACT_DIM],
        }
    }

    /// The advantages of the minibatch `mb_inds`, normalised over it when `ppo.norm-adv`
    /// (every worker computes them alike).
    pub(super) fn advantages(&mut self, shared: &Shared, mb_inds: &[usize]) {
        self.advantages.clear();
        self.advantages
            .extend(mb_inds.iter().map(|&i| shared.batch.b_advantages[i]));
        if shared.learner.ppo.norm_adv {
            normalise_advantages(&mut self.advantages);
        }
    }

    /// Gathers the batch's rows `rows` into the row buffers.
    fn gather(&mut self, shared: &Shared, rows: &[usize]) {
        let b = shared.batch;
        self.x.clear();
        self.actions.clear();
        self.logprobs.clear();
        self.values.clear();
        self.returns.clear();
        for &i in rows {
            self.x.extend_from_slice(&b.b_obs[i * IN..i * IN + OBS_DIM]);
            self.actions
                .extend_from_slice(&b.b_actions[i * ACT_DIM..(i + 1) * ACT_DIM]);
            self.logprobs.push(b.b_logprobs[i]);
            self.values.push(b.b_values[i]);
            self.returns.push(b.b_returns[i]);
        }
    }
}

impl Shared<'_> {
    /// `net`'s item of shard `s` of the minibatch `mb_inds`: gathers its rows, runs the network
    /// forward, through its loss head and back, and leaves the gradient and sums in `out`.
    pub(super) fn item(
        &self,
        params: &[f32],
        mb_inds: &[usize],
        net: Net,
        s: usize,
        ws: &mut Workspace,
        out: &mut ItemOut,
    ) {
        let ppo = &self.learner.ppo;
        let shape = &self.learner.shape;
        let size = ppo.shard_size.max(1);
        let rows = &mb_inds[s * size..((s + 1) * size).min(mb_inds.len())];
        let n = rows.len();
        ws.gather(self, rows);
        let shard_rows = ShardRows {
            actions: &ws.actions,
            logprobs: &ws.logprobs,
            advantages: &ws.advantages[s * size..s * size + n],
            values: &ws.values,
            returns: &ws.returns,
        };
        let settings = HeadSettings {
            clip_coef: ppo.clip_coef as f32,
            clip_vloss: ppo.clip_vloss,
            vf_coef: ppo.vf_coef as f32,
            m: self.minibatch,
        };
        let mlp = &self.nets[net as usize];
        let acts = &mut ws.acts[net as usize];
        let outputs = mlp.forward(params, &ws.x, n, acts);
        let mut sums = ShardSums::default();
        match net {
            Net::Actor => {
                let log_std_block = shape.blocks[shape.log_std_block()];
                let log_std = &params[log_std_block.range()];
                let d_mean = &mut ws.d_out[..n * ACT_DIM];
                let mut d_log_std =
                    policy_head(&shard_rows, outputs, log_std, settings, d_mean, &mut sums);
                if s == 0 {
                    // The entropy bonus belongs to the minibatch once: −ent_coef · ∂H/∂log σ.
                    d_log_std.iter_mut().for_each(|g| *g -= ppo.ent_coef as f32);
                    sums.entropy = Some(gaussian_entropy(log_std));
                }
                mlp.backward(params, &ws.x, n, acts, d_mean, &mut out.grads);
                // The log-std sits at the end of the actor's span.
                let at = log_std_block.offset - net.range(shape).start;
                out.grads[at..at + ACT_DIM].copy_from_slice(&d_log_std);
            }
            Net::Critic => {
                let d_value = &mut ws.d_out[..n];
                value_head(&shard_rows, outputs, settings, d_value, &mut sums);
                mlp.backward(params, &ws.x, n, acts, d_value, &mut out.grads);
            }
        }
        out.sums = sums;
    }
}

/// Entropy of the diagonal Gaussian with log-std `log_std`: `Σ (½ + ½·ln 2π + log σ)`.
fn gaussian_entropy(log_std: &[f32]) -> f64 {
    log_std
        .iter()
        .map(|&l| 0.5 + f64::from(common::policy::HALF_LN_2PI) + f64::from(l))
        .sum()
}
