//! The fused engine: an update's epochs with a hand-derived backward pass instead of burn's
//! autodiff tape, on `ppo.threads` workers.
//!
//! A minibatch is cut into shards of `ppo.shard-size` rows, and each shard into an actor item
//! (forward, the surrogate's [`head`], backward) and a critic item (the same with the value
//! loss); products go through [`matmul`], layers through [`mlp`]. Each item's gradient goes
//! into its own buffer, and a network's shards are added in shard order, so the sum, and with
//! it every weight, is the same for any number of threads: the threads only decide who
//! computes which item ([`plan`]). Each minibatch is three phases, with barriers between them:
//!
//! 1. every worker computes its items at its copy of the parameters;
//! 2. every worker adds up the shards over the parameter parts it owns and publishes their
//!    squared norms;
//! 3. every worker reads the global norm (the parts' norms added in part order), clips, and
//!    takes the Adam step on its parts; a worker whose network has other workers too
//!    publishes its parts, and after a third barrier the others copy them.
//!
//! No worker reads another's items or norms after the second barrier, and none can write the
//! next minibatch's before all have passed the next first barrier, so with one worker per
//! network two barriers a minibatch suffice.
//!
//! With two workers, one trains the actor and the other the critic: all that crosses between
//! them is a few scalars per minibatch. The workers are spawned once per update (not per
//! minibatch) and each shuffles its own copy of the indices with its own copy of the RNG, so
//! all agree on every minibatch without talking. A failure (a non-finite loss or gradient) is
//! seen by all workers alike, and the update returns it with the learner untouched.

mod barrier;
mod head;
mod matmul;
mod mlp;
mod plan;
mod shard;
mod shared;
#[cfg(test)]
mod tests;
mod values;

use std::sync::atomic::Ordering;
use std::sync::{PoisonError, RwLock};

use common::Rng;

use self::barrier::Poisoned;
use self::head::ShardSums;
use self::plan::Net;
use self::shard::Workspace;
use self::shared::{ItemOut, Shared};
use super::Learner;
use super::batch::Batch;
use super::minibatch::MinibatchStats;
use super::update::Optimised;
use crate::LearnerError;
use crate::adam::clip_coef;
use crate::simd::{sum_of_squares, vectorized};

/// A parameter part a worker owns in phases 2 and 3: its Adam moments and summed gradient.
struct OwnedPart {
    part: usize,
    m: Vec<f32>,
    v: Vec<f32>,
    grads: Vec<f32>,
}

/// What one worker returns: its copy of the parameters (current on its own parts), its parts,
/// and (all workers alike) the statistics.
struct WorkerOut {
    params: Vec<f32>,
    owned: Vec<OwnedPart>,
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
        let outs: Vec<Result<WorkerOut, LearnerError>> = std::thread::scope(|s| {
            let helpers: Vec<_> = (1..shared.threads)
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
        let mut params = self.params.clone();
        let mut adam = self.adam.clone();
        let mut first = None;
        for out in outs {
            let out = out?;
            for owned in &out.owned {
                let range = shared.plan.parts[owned.part].range.clone();
                params[range.clone()].copy_from_slice(&out.params[range.clone()]);
                adam.m[range.clone()].copy_from_slice(&owned.m);
                adam.v[range].copy_from_slice(&owned.v);
            }
            first.get_or_insert(out);
        }
        let first = first.expect("at least one worker");
        adam.step += first.minibatches;
        Ok(Optimised {
            params,
            adam,
            rng: first.rng,
            sums: first.sums,
            epochs_run: first.epochs,
        })
    }
}

impl<'a> Shared<'a> {
    /// Worker `w`'s part of the update, or the error every worker sees alike.
    fn work(&self, w: usize, mut b_inds: Vec<usize>) -> Result<WorkerOut, LearnerError> {
        let _guard = self.barrier.guard();
        let ppo = &self.learner.ppo;
        let mut rng = self.learner.rng.clone();
        let mut params = self.learner.params.clone();
        let mut ws = Workspace::new(self, ppo.shard_size.max(1).min(self.minibatch));
        let mut owned: Vec<OwnedPart> = self.plan.owned[w]
            .iter()
            .map(|&part| {
                let r = self.plan.parts[part].range.clone();
                OwnedPart {
                    part,
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
                self.compute_items(w, &params, mb_inds, &mut ws);
                self.wait()?;
                let total = self.sum_parts(&mut owned);
                self.wait()?;
                let stats = self.step(&mut owned, &mut params, &total, &mut t)?;
                if self.plan.shares_any() {
                    self.wait()?;
                    self.copy_parts(w, &mut params);
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
            owned,
            sums,
            epochs,
            minibatches: t - self.adam.step,
            rng,
        })
    }

    /// Phase 1: worker `w`'s items of the minibatch `mb_inds` at `params`.
    fn compute_items(&self, w: usize, params: &[f32], mb_inds: &[usize], ws: &mut Workspace) {
        ws.advantages(self, mb_inds);
        for net in Net::BOTH {
            for s in (0..self.shards).filter(|&s| self.plan.worker(net, s) == w) {
                let mut out = self.items[net as usize][s]
                    .write()
                    .unwrap_or_else(PoisonError::into_inner);
                self.item(params, mb_inds, net, s, ws, &mut out);
            }
        }
    }

    /// Phase 2: the owned parts of the gradient, added over shards in shard order, and their
    /// squared norms; returns the minibatch's loss sums, added in item order.
    fn sum_parts(&self, owned: &mut [OwnedPart]) -> ShardSums {
        let mut total = ShardSums::default();
        self.items
            .iter()
            .flatten()
            .for_each(|i| total.add(&read(i).sums));
        let shape = &self.learner.shape;
        for o in owned {
            let part = &self.plan.parts[o.part];
            let origin = part.net.range(shape).start;
            let local = part.range.start - origin..part.range.end - origin;
            let shards = &self.items[part.net as usize];
            o.grads
                .copy_from_slice(&read(&shards[0]).grads[local.clone()]);
            for s in &shards[1..] {
                let s = read(s);
                vectorized(|| {
                    o.grads
                        .iter_mut()
                        .zip(&s.grads[local.clone()])
                        .for_each(|(a, x)| *a += x);
                });
            }
            self.part_norms[o.part].store(sum_of_squares(&o.grads).to_bits(), Ordering::Relaxed);
        }
        total
    }

    /// Phase 3: clips by the global norm and steps the owned parts, publishing them where
    /// other workers compute their network. `t` counts Adam's steps.
    fn step(
        &self,
        owned: &mut [OwnedPart],
        params: &mut [f32],
        total: &ShardSums,
        t: &mut u64,
    ) -> Result<MinibatchStats, LearnerError> {
        let norm = self
            .part_norms
            .iter()
            .map(|n| f64::from_bits(n.load(Ordering::Relaxed)))
            .sum::<f64>()
            .sqrt() as f32;
        let stats = self.stats(total, norm);
        if !(stats.pg_loss.is_finite() && stats.v_loss.is_finite() && norm.is_finite()) {
            return Err(LearnerError::NonFinite {
                update: self.learner.counters.update + 1,
                what: "loss or gradient",
            });
        }
        let coef = clip_coef(norm, self.learner.ppo.max_grad_norm as f32);
        *t += 1;
        let step = self.adam.at(*t, self.lr);
        for o in owned {
            let part = &self.plan.parts[o.part];
            let mine = &mut params[part.range.clone()];
            step.apply(mine, &o.grads, coef.unwrap_or(1.0), &mut o.m, &mut o.v);
            if self.plan.shared(part.net) {
                self.parts[o.part]
                    .write()
                    .unwrap_or_else(PoisonError::into_inner)
                    .copy_from_slice(mine);
            }
        }
        Ok(stats)
    }

    /// After phase 3: worker `w` copies the parts other workers stepped of the networks it
    /// computes.
    fn copy_parts(&self, w: usize, params: &mut [f32]) {
        for (p, part) in self.plan.parts.iter().enumerate() {
            if self.plan.shared(part.net)
                && self.plan.computes(w, part.net)
                && !self.plan.owned[w].contains(&p)
            {
                params[part.range.clone()]
                    .copy_from_slice(&self.parts[p].read().unwrap_or_else(PoisonError::into_inner));
            }
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

    /// One minibatch's means from the items' sums, as the burn engine reports them.
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

/// An item's output, for reading after the barrier that ends phase 1.
fn read(item: &RwLock<ItemOut>) -> std::sync::RwLockReadGuard<'_, ItemOut> {
    item.read().unwrap_or_else(PoisonError::into_inner)
}
