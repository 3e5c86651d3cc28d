//! Many envs stepped together by a small fixed set of threads. Each env owns its world and
//! RNG stream, so the result does not depend on the thread count.

use crate::env::{Env, SharedTerrain, StepInfo};
use crate::pool::Pool;
use common::config::SimConfig;
use common::{ACT_DIM, OBS_DIM};
use std::sync::{Mutex, PoisonError};

/// All envs of a run.
pub struct Fleet {
    pub envs: Vec<Env>,
    pool: Pool,
}

impl Fleet {
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

    /// Every env leaves its episode and starts the next from a random pose ([`Env::restart`]).
    pub fn restart(&mut self) {
        self.envs.iter_mut().for_each(Env::restart);
    }

    pub fn observe(&self, obs: &mut [[f32; OBS_DIM]]) {
        for (o, e) in obs.iter_mut().zip(&self.envs) {
            *o = e.observe();
        }
    }

    /// Steps every env with its action, writing each env's step info and next observation.
    pub fn step(
        &mut self,
        actions: &[[f32; ACT_DIM]],
        infos: &mut [StepInfo],
        obs: &mut [[f32; OBS_DIM]],
    ) {
        self.decide_and_step(actions.iter(), &|_, a| *a, infos, obs);
    }

    /// Steps every env with the action `decide` picks for env `i` from its own item of
    /// `lanes` (e.g. its random stream), writing each env's step info and next observation. Deciding runs on the pool's threads beside the physics, so
    /// a policy's forward passes do not wait for one thread.
    ///
    /// The threads take the envs one at a time, in order, so a thread the scheduler holds
    /// back (a reader or the learner on the same core) delays one env, not its share of the
    /// fleet.
    pub fn decide_and_step<T: Send>(
        &mut self,
        lanes: impl Iterator<Item = T> + Send,
        decide: &(dyn Fn(usize, T) -> [f32; ACT_DIM] + Sync),
        infos: &mut [StepInfo],
        obs: &mut [[f32; OBS_DIM]],
    ) {
        // One shared iterator: each thread takes the next env under the lock and steps it
        // outside, so nothing is allocated per tick.
        let work = Mutex::new(
            self.envs
                .iter_mut()
                .enumerate()
                .zip(lanes)
                .zip(infos)
                .zip(obs),
        );
        self.pool.run(&|_| {
            loop {
                let next = work.lock().unwrap_or_else(PoisonError::into_inner).next();
                let Some(((((i, e), lane), info), o)) = next else {
                    break;
                };
                *info = e.step(decide(i, lane));
                *o = e.observe();
            }
        });
    }
}
