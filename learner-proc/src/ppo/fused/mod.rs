//! The fused engine: an update's epochs with a hand-derived backward pass instead of burn's
//! autodiff tape, on `ppo.threads` workers.
//!
//! A minibatch is cut into shards of `ppo.shard-size` rows. Each shard's loss gradient
//! (forward, [`head`], backward: [`mlp`], products through [`matmul`]) goes into its own
//! buffer, and the shards are added in shard order, so the sum, and with it every weight,
//! is the same for any number of threads: the threads only decide who computes which shard.
//! Each minibatch is three phases between barriers:
//!
//! 1. every worker computes its shards' gradients (shard `s` to worker `s mod threads`);
//! 2. every worker adds up the shards over its own parameter blocks and publishes their
//!    squared norm;
//! 3. every worker reads the global norm (block norms added in block order), clips, and
//!    takes the Adam step on its blocks; after the barrier each copies the blocks it does not
//!    own into its own copy of the parameters (no lock is ever contended).
//!
//! The workers are spawned once per update (not per minibatch) and each shuffles its own copy
//! of the indices with its own copy of the RNG, so all agree on every minibatch without
//! talking. A failure (a non-finite loss or gradient) is seen by all workers alike, and the
//! update returns it with the learner untouched.

mod barrier;
mod head;
mod matmul;
mod mlp;
#[cfg(test)]
mod tests;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{PoisonError, RwLock};

use common::{ACT_DIM, OBS_DIM, Rng};

use self::barrier::{Poisoned, SpinBarrier};
use self::head::{HeadSettings, ShardRows, ShardSums, policy_head, value_head};
use self::mlp::{Activations, Mlp};
use super::batch::Batch;
use super::minibatch::{MinibatchStats, normalise_advantages};
use super::update::Optimised;
use super::{IN, Learner};
use crate::LearnerError;
use crate::adam::{Adam, clip_coef};
use crate::simd::{sum_of_squares, vectorized};
use crate::net::ParamBlock;

/// A shard's output: its gradient over the whole parameter vector and its loss sums.
struct ShardOut {
    grads: Vec<f32>,
    sums: ShardSums,
}

/// What the workers share for one update.
struct Shared<'a> {
    learner: &'a Learner,
    batch: &'a Batch,
    actor: Mlp,
    critic: Mlp,
    threads: usize,
    minibatch: usize,
    minibatches: usize,
    shards: Vec<RwLock<ShardOut>>,
    /// Each block's squared gradient norm (f64 bits), written by its owner in phase 2.
    block_norms: Vec<AtomicU64>,
    /// Each parameter block's values after the last step, written by its owner in phase 3
    /// and copied by every other worker into its own full copy of the parameters.
    blocks: Vec<RwLock<Vec<f32>>>,
    /// The blocks each worker owns in phases 2 and 3.
    owned: Vec<Vec<usize>>,
    adam: &'a Adam,
    lr: f32,
    barrier: SpinBarrier,
}

/// A parameter block a worker owns in phases 2 and 3: its Adam moments and summed gradient.
struct OwnedBlock {
    block: usize,
    m: Vec<f32>,
    v: Vec<f32>,
    grads: Vec<f32>,
}

/// What one worker returns: its blocks, and (all workers alike) the statistics.
struct WorkerOut {
    params: Vec<f32>,
    blocks: Vec<OwnedBlock>,
    sums: MinibatchStats,
    epochs: usize,
    minibatches: u64,
    rng: Rng,
}

impl Learner {
    /// The epochs of one update on the fused engine (see the module doc); `b_inds` are the
    /// transitions to train on.
    pub(super) fn optimise_fused(
        &self,
        batch: &Batch,
        b_inds: Vec<usize>,
        lr: f32,
    ) -> Result<Optimised, LearnerError> {
        let shared = Shared::new(self, batch, b_inds.len(), self.threads, lr);
        let threads = shared.threads;
        let outs: Vec<Result<WorkerOut, LearnerError>> = std::thread::scope(|s| {
            let helpers: Vec<_> = (1..threads)
                .map(|w| {
                    let (shared, b_inds) = (&shared, b_inds.clone());
                    s.spawn(move || shared.work(w, b_inds))
                })
                .collect();
            let mut outs = vec![shared.work(0, b_inds)];
            for helper in helpers {
                outs.push(
                    helper
                        .join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
                );
            }
            outs
        });
        let mut adam = self.adam.clone();
        let mut first = None;
        for out in outs {
            let out = out?;
            for owned in &out.blocks {
                let range = self.shape.blocks[owned.block].range();
                adam.m[range.clone()].copy_from_slice(&owned.m);
                adam.v[range].copy_from_slice(&owned.v);
            }
            first.get_or_insert(out);
        }
        let first = first.expect("at least one worker");
        adam.step += first.minibatches;
        Ok(Optimised {
            params: first.params,
            adam,
            rng: first.rng,
            sums: first.sums,
            epochs_run: first.epochs,
        })
    }
}

impl<'a> Shared<'a> {
    /// For an update of `learner` on `batch` that trains on `train` transitions, with up to
    /// `threads` workers (no more than a minibatch has shards).
    fn new(learner: &'a Learner, batch: &'a Batch, train: usize, threads: usize, lr: f32) -> Self {
        let minibatch = learner.ppo.minibatch_size.min(train);
        let n_shards = minibatch.div_ceil(learner.ppo.shard_size.max(1));
        let threads = threads.clamp(1, n_shards);
        let shape = &learner.shape;
        Shared {
            learner,
            batch,
            actor: Mlp::new(shape.dense(false).collect()),
            critic: Mlp::new(shape.dense(true).collect()),
            threads,
            minibatch,
            // Full minibatches only (as ML-Agents); the remainder differs per epoch's shuffle.
            minibatches: train / minibatch,
            shards: (0..n_shards)
                .map(|_| {
                    RwLock::new(ShardOut {
                        grads: vec![0.0; shape.len()],
                        sums: ShardSums::default(),
                    })
                })
                .collect(),
            block_norms: shape.blocks.iter().map(|_| AtomicU64::new(0)).collect(),
            blocks: shape
                .blocks
                .iter()
                .map(|b| RwLock::new(learner.params[b.range()].to_vec()))
                .collect(),
            owned: assign_blocks(&shape.blocks, threads),
            adam: &learner.adam,
            lr,
            barrier: SpinBarrier::new(threads),
        }
    }

    /// Worker `w`'s part of the update, or the error every worker sees alike.
    fn work(&self, w: usize, mut b_inds: Vec<usize>) -> Result<WorkerOut, LearnerError> {
        let _guard = self.barrier.guard();
        let ppo = &self.learner.ppo;
        let shape = &self.learner.shape;
        let mut rng = self.learner.rng.clone();
        let mut params = self.learner.params.clone();
        let mut ws = Workspace::new(self, ppo.shard_size.max(1).min(self.minibatch));
        let mut owned: Vec<OwnedBlock> = self.owned[w]
            .iter()
            .map(|&block| {
                let r = shape.blocks[block].range();
                OwnedBlock {
                    block,
                    m: self.adam.m[r.clone()].to_vec(),
                    v: self.adam.v[r.clone()].to_vec(),
                    grads: vec![0.0; r.len()],
                }
            })
            .collect();
        let mut sums = MinibatchStats::default();
        let (mut epochs, mut t) = (0, self.adam.step);
        for _epoch in 0..ppo.epochs {
            rng.shuffle(&mut b_inds);
            let mut approx_kl = 0.0;
            for k in 0..self.minibatches {
                let mb_inds = &b_inds[k * self.minibatch..(k + 1) * self.minibatch];
                self.compute_shards(w, &params, mb_inds, &mut ws);
                self.wait()?;

                // Phase 2: this worker's blocks of the summed gradient, and their norms.
                let mut total = ShardSums::default();
                let shards: Vec<_> = self
                    .shards
                    .iter()
                    .map(|s| s.read().unwrap_or_else(PoisonError::into_inner))
                    .collect();
                shards.iter().for_each(|s| total.add(&s.sums));
                for o in &mut owned {
                    let (g, b) = (&mut o.grads, o.block);
                    let range = shape.blocks[b].range();
                    g.copy_from_slice(&shards[0].grads[range.clone()]);
                    for s in &shards[1..] {
                        vectorized(|| {
                            g.iter_mut()
                                .zip(&s.grads[range.clone()])
                                .for_each(|(a, x)| *a += x);
                        });
                    }
                    self.block_norms[b].store(sum_of_squares(g).to_bits(), Ordering::Relaxed);
                }
                drop(shards);
                self.wait()?;

                // Phase 3: clip by the global norm and step.
                let norm = self
                    .block_norms
                    .iter()
                    .map(|n| f64::from_bits(n.load(Ordering::Relaxed)))
                    .sum::<f64>()
                    .sqrt() as f32;
                let stats = self.stats(&total, norm);
                if !(stats.pg_loss.is_finite() && stats.v_loss.is_finite() && norm.is_finite()) {
                    return Err(LearnerError::NonFinite {
                        update: self.learner.counters.update + 1,
                        what: "loss or gradient",
                    });
                }
                let coef = clip_coef(norm, ppo.max_grad_norm as f32);
                t += 1;
                let step = self.adam.at(t, self.lr);
                for o in &mut owned {
                    if let Some(c) = coef {
                        vectorized(|| o.grads.iter_mut().for_each(|x| *x *= c));
                    }
                    let mine = &mut params[shape.blocks[o.block].range()];
                    step.apply(mine, &o.grads, &mut o.m, &mut o.v);
                    self.blocks[o.block]
                        .write()
                        .unwrap_or_else(PoisonError::into_inner)
                        .copy_from_slice(mine);
                }
                self.wait()?;
                for (b, block) in self.blocks.iter().enumerate() {
                    if !self.owned[w].contains(&b) {
                        params[shape.blocks[b].range()]
                            .copy_from_slice(&block.read().unwrap_or_else(PoisonError::into_inner));
                    }
                }
                sums.add(&stats);
                approx_kl = stats.approx_kl;
            }
            epochs += 1;
            // CleanRL's early stop looks at the epoch's last minibatch.
            if ppo.target_kl.is_some_and(|kl| approx_kl > kl) {
                break;
            }
        }
        Ok(WorkerOut {
            params,
            blocks: owned,
            sums,
            epochs,
            minibatches: t - self.adam.step,
            rng,
        })
    }

    /// Phase 1: worker `w`'s shards of the minibatch `mb_inds` at `params`.
    fn compute_shards(&self, w: usize, params: &[f32], mb_inds: &[usize], ws: &mut Workspace) {
        ws.advantages.clear();
        ws.advantages
            .extend(mb_inds.iter().map(|&i| self.batch.b_advantages[i]));
        if self.learner.ppo.norm_adv {
            normalise_advantages(&mut ws.advantages);
        }
        for s in (w..self.shards.len()).step_by(self.threads) {
            let mut out = self.shards[s]
                .write()
                .unwrap_or_else(PoisonError::into_inner);
            self.shard(params, mb_inds, s, ws, &mut out);
        }
    }

    fn wait(&self) -> Result<(), LearnerError> {
        self.barrier
            .wait()
            .map_err(|Poisoned| LearnerError::Tensor {
                what: "update",
                reason: "another update worker failed".into(),
            })
    }

    /// Shard `s` of the minibatch `mb_inds`: gathers its rows, runs both networks forward and
    /// back, and leaves its gradient and loss sums in `out`.
    fn shard(
        &self,
        params: &[f32],
        mb_inds: &[usize],
        s: usize,
        ws: &mut Workspace,
        out: &mut ShardOut,
    ) {
        let ppo = &self.learner.ppo;
        let shape = &self.learner.shape;
        let size = ppo.shard_size.max(1);
        let rows = &mb_inds[s * size..((s + 1) * size).min(mb_inds.len())];
        let n = rows.len();
        let b = self.batch;
        ws.x.clear();
        ws.actions.clear();
        ws.logprobs.clear();
        ws.values.clear();
        ws.returns.clear();
        for &i in rows {
            ws.x.extend_from_slice(&b.b_obs[i * IN..i * IN + OBS_DIM]);
            ws.actions
                .extend_from_slice(&b.b_actions[i * ACT_DIM..(i + 1) * ACT_DIM]);
            ws.logprobs.push(b.b_logprobs[i]);
            ws.values.push(b.b_values[i]);
            ws.returns.push(b.b_returns[i]);
        }
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
        let log_std_block = shape.blocks[shape.log_std_block()];
        let log_std = &params[log_std_block.range()];
        let mut sums = ShardSums::default();
        let mean = self.actor.forward(params, &ws.x, n, &mut ws.actor);
        let d_mean = &mut ws.d_mean[..n * ACT_DIM];
        let mut d_log_std = policy_head(&shard_rows, mean, log_std, settings, d_mean, &mut sums);
        let value = self.critic.forward(params, &ws.x, n, &mut ws.critic);
        let d_value = &mut ws.d_value[..n];
        value_head(&shard_rows, value, settings, d_value, &mut sums);
        if s == 0 {
            // The entropy bonus belongs to the minibatch once: −ent_coef · ∂H/∂log σ = −ent_coef.
            d_log_std.iter_mut().for_each(|g| *g -= ppo.ent_coef as f32);
            sums.entropy = Some(gaussian_entropy(log_std));
        }
        self.actor
            .backward(params, &ws.x, n, &mut ws.actor, d_mean, &mut out.grads);
        self.critic
            .backward(params, &ws.x, n, &mut ws.critic, d_value, &mut out.grads);
        out.grads[log_std_block.range()].copy_from_slice(&d_log_std);
        out.sums = sums;
    }

    /// One minibatch's means from the shards' sums, as the burn engine reports them.
    fn stats(&self, total: &ShardSums, grad_norm: f32) -> MinibatchStats {
        let m = self.minibatch as f64;
        MinibatchStats {
            pg_loss: total.pg_loss / m,
            v_loss: 0.5 * total.v_loss / m,
            entropy: total.entropy.unwrap_or(f64::NAN),
            old_approx_kl: total.old_approx_kl / m,
            approx_kl: total.approx_kl / m,
            clipfrac: total.clipped / m,
            grad_norm: f64::from(grad_norm),
        }
    }
}

/// Entropy of the diagonal Gaussian with log-std `log_std`: `Σ (½ + ½·ln 2π + log σ)`.
fn gaussian_entropy(log_std: &[f32]) -> f64 {
    log_std
        .iter()
        .map(|&l| 0.5 + f64::from(common::policy::HALF_LN_2PI) + f64::from(l))
        .sum()
}

/// Gives each worker parameter blocks of about equal size (largest first, to the least
/// loaded worker); which worker owns a block changes no result.
fn assign_blocks(blocks: &[ParamBlock], threads: usize) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    order.sort_by_key(|&b| std::cmp::Reverse(blocks[b].range().len()));
    let mut owned = vec![Vec::new(); threads];
    let mut load = vec![0usize; threads];
    for b in order {
        let w = (0..threads).min_by_key(|&w| load[w]).unwrap_or(0);
        load[w] += blocks[b].range().len();
        owned[w].push(b);
    }
    owned.iter_mut().for_each(|o| o.sort_unstable());
    owned
}

/// One worker's buffers, allocated once per update for a shard's rows.
struct Workspace {
    x: Vec<f32>,
    actions: Vec<f32>,
    logprobs: Vec<f32>,
    values: Vec<f32>,
    returns: Vec<f32>,
    /// The whole minibatch's advantages, normalised.
    advantages: Vec<f32>,
    actor: Activations,
    critic: Activations,
    d_mean: Vec<f32>,
    d_value: Vec<f32>,
}

impl Workspace {
    fn new(shared: &Shared, rows: usize) -> Self {
        Self {
            x: Vec::with_capacity(rows * OBS_DIM),
            actions: Vec::with_capacity(rows * ACT_DIM),
            logprobs: Vec::with_capacity(rows),
            values: Vec::with_capacity(rows),
            returns: Vec::with_capacity(rows),
            advantages: Vec::with_capacity(shared.minibatch),
            actor: shared.actor.buffers(rows),
            critic: shared.critic.buffers(rows),
            d_mean: vec![0.0; rows * ACT_DIM],
            d_value: vec![0.0; rows],
        }
    }
}
