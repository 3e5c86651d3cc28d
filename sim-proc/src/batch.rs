//! Many envs stepped together by a small fixed set of threads. Each env owns its world and
//! RNG stream, so the result does not depend on the thread count.

use crate::env::{Env, SharedTerrain, StepInfo};
use crate::pool::Pool;
use common::config::SimConfig;
use common::{ACT_DIM, OBS_DIM};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// All envs of a run.
pub struct Batch {
    pub envs: Vec<Env>,
    pool: Pool,
}

impl Batch {
    pub fn new(cfg: &SimConfig, terrain: &SharedTerrain, seed: u64) -> Self {
        let envs: Vec<Env> = (0..cfg.num_envs())
            .map(|i| Env::new(i, cfg, terrain, seed))
            .collect();
        let pool = Pool::new(cfg.threads.min(envs.len()));
        Self { envs, pool }
    }

    pub fn len(&self) -> usize {
        self.envs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.envs.is_empty()
    }

    pub fn observe(&self, obs: &mut [[f32; OBS_DIM]]) {
        for (o, e) in obs.iter_mut().zip(&self.envs) {
            *o = e.observe();
        }
    }

    /// Steps every env with its action, writing each env's step info and next observation.
    /// The threads take the envs one at a time, in order, so a thread the scheduler holds
    /// back (a reader or the learner on the same core) delays one env, not its share of the
    /// batch.
    pub fn step(
        &mut self,
        actions: &[[f32; ACT_DIM]],
        infos: &mut [StepInfo],
        obs: &mut [[f32; OBS_DIM]],
    ) {
        // Each env is taken by exactly one thread; the mutex only proves that to the compiler.
        let work: Vec<Mutex<Option<_>>> = self
            .envs
            .iter_mut()
            .zip(actions)
            .zip(infos)
            .zip(obs)
            .map(|one| Mutex::new(Some(one)))
            .collect();
        let next = AtomicUsize::new(0);
        self.pool.run(&|_| {
            while let Some(one) = work.get(next.fetch_add(1, Ordering::Relaxed)) {
                let taken = one.lock().unwrap_or_else(PoisonError::into_inner).take();
                if let Some((((e, a), i), o)) = taken {
                    *i = e.step(*a);
                    *o = e.observe();
                }
            }
        });
    }
}
