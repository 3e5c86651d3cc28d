//! Many envs stepped together by a small fixed set of threads. Each env owns its world and
//! RNG stream, so the result does not depend on the thread count.

use crate::env::{Env, SharedTerrain, StepInfo};
use common::config::SimConfig;
use common::{ACT_DIM, OBS_DIM};

/// All envs of a run.
pub struct Batch {
    pub envs: Vec<Env>,
    threads: usize,
}

impl Batch {
    pub fn new(cfg: &SimConfig, terrain: &SharedTerrain, seed: u64) -> Self {
        let envs = (0..cfg.num_envs())
            .map(|i| Env::new(i, cfg, terrain, seed))
            .collect();
        Self {
            envs,
            threads: cfg.threads.max(1),
        }
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
    pub fn step(
        &mut self,
        actions: &[[f32; ACT_DIM]],
        infos: &mut [StepInfo],
        obs: &mut [[f32; OBS_DIM]],
    ) {
        let n = self.envs.len();
        let threads = self.threads.min(n).max(1);
        let chunk = n.div_ceil(threads);
        let work = |envs: &mut [Env],
                    acts: &[[f32; ACT_DIM]],
                    infos: &mut [StepInfo],
                    obs: &mut [[f32; OBS_DIM]]| {
            for (((e, a), i), o) in envs
                .iter_mut()
                .zip(acts)
                .zip(infos.iter_mut())
                .zip(obs.iter_mut())
            {
                *i = e.step(*a);
                *o = e.observe();
            }
        };
        if threads == 1 {
            work(&mut self.envs, actions, infos, obs);
            return;
        }
        std::thread::scope(|s| {
            let parts = self
                .envs
                .chunks_mut(chunk)
                .zip(actions.chunks(chunk))
                .zip(infos.chunks_mut(chunk))
                .zip(obs.chunks_mut(chunk));
            let mut parts: Vec<_> = parts.collect();
            // The calling thread takes the last chunk instead of idling.
            let last = parts.pop();
            for (((e, a), i), o) in parts {
                s.spawn(move || work(e, a, i, o));
            }
            if let Some((((e, a), i), o)) = last {
                work(e, a, i, o);
            }
        });
    }
}
