//! What the workers of one update share: the learner and batch, the networks, the plan of
//! who computes which item, each item's output, the parts' norms and values, and the barrier.

use std::sync::RwLock;
use std::sync::atomic::AtomicU64;

use super::barrier::SpinBarrier;
use super::head::ShardSums;
use super::mlp::Mlp;
use super::plan::{Net, Plan};
use crate::adam::Adam;
use crate::ppo::Learner;
use crate::ppo::batch::Batch;

/// What the workers share for one update.
pub(super) struct Shared<'a> {
    pub(super) learner: &'a Learner,
    pub(super) batch: &'a Batch,
    /// The actor and the critic, indexed by [`Net`].
    pub(super) nets: [Mlp; 2],
    pub(super) threads: usize,
    pub(super) minibatch: usize,
    pub(super) minibatches: usize,
    pub(super) shards: usize,
    pub(super) plan: Plan,
    /// Each network's items, `[net][shard]`, written by their workers in phase 1.
    pub(super) items: [Vec<RwLock<ItemOut>>; 2],
    /// Each part's squared gradient norm (f64 bits), written by its owner in phase 2.
    pub(super) part_norms: Vec<AtomicU64>,
    /// Each part's values after the last step, published by its owner in phase 3 when other
    /// workers compute its network.
    pub(super) parts: Vec<RwLock<Vec<f32>>>,
    pub(super) adam: &'a Adam,
    pub(super) lr: f32,
    pub(super) barrier: SpinBarrier,
}

/// An item's output: its network's gradient (over that network's span of the parameters) and
/// its loss sums.
pub(super) struct ItemOut {
    pub(super) grads: Vec<f32>,
    pub(super) sums: ShardSums,
}

impl ItemOut {
    pub(super) fn new(len: usize) -> Self {
        Self {
            grads: vec![0.0; len],
            sums: ShardSums::default(),
        }
    }
}

impl<'a> Shared<'a> {
    /// For an update of `learner` on `batch` that trains on `train` transitions, with up to
    /// `threads` workers (no more than a minibatch has items).
    pub(super) fn new(
        learner: &'a Learner,
        batch: &'a Batch,
        train: usize,
        threads: usize,
        lr: f32,
    ) -> Self {
        let minibatch = learner.ppo.minibatch_size.min(train);
        let shards = minibatch.div_ceil(learner.ppo.shard_size.max(1));
        let threads = threads.clamp(1, 2 * shards);
        let shape = &learner.shape;
        let plan = Plan::new(shape, threads);
        let items = Net::BOTH.map(|net| {
            (0..shards)
                .map(|_| RwLock::new(ItemOut::new(net.range(shape).len())))
                .collect()
        });
        Shared {
            learner,
            batch,
            nets: Net::BOTH.map(|net| {
                Mlp::new(
                    shape.dense(net == Net::Critic).collect(),
                    net.range(shape).start,
                )
            }),
            threads,
            minibatch,
            // Full minibatches only (as ML-Agents); the remainder differs per epoch's shuffle.
            minibatches: train / minibatch,
            shards,
            items,
            part_norms: plan.parts.iter().map(|_| AtomicU64::new(0)).collect(),
            parts: plan
                .parts
                .iter()
                .map(|p| RwLock::new(learner.params[p.range.clone()].to_vec()))
                .collect(),
            plan,
            adam: &learner.adam,
            lr,
            barrier: SpinBarrier::new(threads),
        }
    }
}
