//! Many envs stepped together by a small fixed set of threads. Each env owns its world and
//! RNG stream, so the result does not depend on the thread count.

use crate::env::{Env, SharedTerrain, StepInfo};
use crate::pool::Pool;
use common::config::SimConfig;
use common::{ACT_DIM, OBS_DIM};
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
    /// The envs are cut into one contiguous run per thread.
    pub fn step(
        &mut self,
        actions: &[[f32; ACT_DIM]],
        infos: &mut [StepInfo],
        obs: &mut [[f32; OBS_DIM]],
    ) {
        let chunk = self.envs.len().div_ceil(self.pool.parts()).max(1);
        // Each part is taken by exactly one thread; the mutex only proves that to the compiler.
        let parts: Vec<Mutex<Option<_>>> = self
            .envs
            .chunks_mut(chunk)
            .zip(actions.chunks(chunk))
            .zip(infos.chunks_mut(chunk))
            .zip(obs.chunks_mut(chunk))
            .map(|part| Mutex::new(Some(part)))
            .collect();
        self.pool.run(&|k| {
            let part = parts
                .get(k)
                .and_then(|p| p.lock().unwrap_or_else(PoisonError::into_inner).take());
            if let Some((((envs, acts), infos), obs)) = part {
                for (((e, a), i), o) in envs.iter_mut().zip(acts).zip(infos).zip(obs) {
                    *i = e.step(*a);
                    *o = e.observe();
                }
            }
        });
    }
}
