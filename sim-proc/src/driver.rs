//! Acting and recording: one decision step of every env under a policy, appended to a rollout
//! chunk as [`Transition`]s. Shared by `serve` and by in-process training loops, so both
//! produce the same transitions from the same seed.

use crate::Fleet;
use crate::controllers::Actor;
use crate::env::StepInfo;
use crate::switching::PolicySet;
use crate::task::Ending;
use common::config::PolicySlot;
use common::episode::EpisodeStats;
use common::wire::{self, EnvTick};
use common::{ACT_DIM, OBS_DIM, Transition};

/// What one env did in the last step, and who chose it.
#[derive(Clone, Copy)]
struct Choice {
    action: [f32; ACT_DIM],
    logprob: f32,
    slot: PolicySlot,
    version: u32,
}

impl Default for Choice {
    fn default() -> Self {
        Self {
            action: [0.0; ACT_DIM],
            logprob: 0.0,
            slot: PolicySlot::General,
            version: 0,
        }
    }
}

/// Per-env buffers of the acting loop.
pub struct Driver {
    /// Each env's current observation.
    pub obs: Vec<[f32; OBS_DIM]>,
    next_obs: Vec<[f32; OBS_DIM]>,
    /// Each env's random stream and scratch space for sampling its actions.
    actors: Vec<Actor>,
    /// The last step's choice, per env.
    chosen: Vec<Choice>,
    /// What the last step produced, per env.
    pub infos: Vec<StepInfo>,
    /// Every episode ended so far, counted here where it ends.
    pub episodes: EpisodeStats,
}

impl Driver {
    /// Buffers for `fleet`; env `i` samples its actions from the stream `seed` derives for it.
    pub fn new(fleet: &Fleet, seed: u64) -> Self {
        let n = fleet.len();
        let mut obs = vec![[0.0f32; OBS_DIM]; n];
        fleet.observe(&mut obs);
        Self {
            next_obs: obs.clone(),
            obs,
            actors: (0..n).map(|i| Actor::for_env(seed, i)).collect(),
            chosen: vec![Choice::default(); n],
            infos: vec![StepInfo::default(); n],
            episodes: EpisodeStats::default(),
        }
    }

    /// Samples every env's action from `policies` (env `i` asks for slot `wanted[i]`), steps
    /// the fleet and appends one transition per env to `chunk`. `classes` holds the
    /// estimator's current class per env. Each env samples on the thread that steps it.
    pub fn tick(
        &mut self,
        fleet: &mut Fleet,
        policies: &PolicySet,
        wanted: &[PolicySlot],
        classes: &[u8],
        chunk: &mut Vec<Transition>,
    ) {
        let obs = &self.obs;
        fleet.decide_and_step(
            self.actors.iter_mut().zip(self.chosen.iter_mut()),
            &|i, (actor, chosen)| {
                let w = wanted.get(i).copied().unwrap_or(PolicySlot::General);
                let (slot, version, action, logprob) = policies.sample(w, &obs[i], actor);
                *chosen = Choice {
                    action,
                    logprob,
                    slot,
                    version,
                };
                action
            },
            &mut self.infos,
            &mut self.next_obs,
        );
        self.count_endings();
        for (i, env) in fleet.envs.iter().enumerate() {
            let (info, chosen) = (&self.infos[i], &self.chosen[i]);
            let end = info.ending;
            chunk.push(Transition {
                obs: self.obs[i],
                action: chosen.action,
                final_obs: info.final_obs,
                logprob: chosen.logprob,
                reward: info.reward as f32,
                policy_version: chosen.version,
                slot: chosen.slot.index() as u8,
                env: i as u32,
                terminated: u8::from(end.is_some_and(super::task::Ending::terminated)),
                truncated: u8::from(end.is_some_and(super::task::Ending::truncated)),
                success: u8::from(end == Some(Ending::Success)),
                area: env.ground().code(),
                estimated_class: classes.get(i).copied().unwrap_or(wire::CLASS_UNKNOWN),
                ..Transition::default()
            });
        }
        std::mem::swap(&mut self.obs, &mut self.next_obs);
    }

    /// Steps the fleet with actions chosen outside the sim (a gym client's); the slot that
    /// acted stays `general` at version 0.
    pub fn step_with(&mut self, fleet: &mut Fleet, actions: &[[f32; ACT_DIM]]) {
        fleet.step(actions, &mut self.infos, &mut self.next_obs);
        self.count_endings();
        std::mem::swap(&mut self.obs, &mut self.next_obs);
    }

    /// Observes the envs again after they were rebuilt or restarted outside a step; the
    /// episode counts go on.
    pub fn restart(&mut self, fleet: &Fleet) {
        fleet.observe(&mut self.obs);
        self.infos.fill(StepInfo::default());
    }

    fn count_endings(&mut self) {
        for info in &self.infos {
            if let Some(e) = info.ending {
                self.episodes
                    .record(e == Ending::Success, u64::from(info.episode_steps));
            }
        }
    }

    /// The slot that chose env `i`'s last action.
    pub fn slot(&self, i: usize) -> PolicySlot {
        self.chosen[i].slot
    }

    /// Appends each env's bootstrap observation (the chunk's tail, DESIGN §2).
    pub fn bootstrap(&self, chunk: &mut Vec<Transition>) {
        chunk.extend(self.obs.iter().enumerate().map(|(i, o)| Transition {
            obs: *o,
            env: i as u32,
            ..Transition::default()
        }));
    }

    /// The telemetry of the last step, one entry per env.
    pub fn env_ticks(&self, fleet: &Fleet, out: &mut [EnvTick]) {
        for (((t, env), info), chosen) in out
            .iter_mut()
            .zip(&fleet.envs)
            .zip(&self.infos)
            .zip(&self.chosen)
        {
            let p = env.pose();
            let imu = env.imu_euler().unwrap_or([f64::NAN; 3]);
            let events = info.ending.map_or(0, |e| {
                let kind = if e.terminated() {
                    wire::EVENT_TERMINATED
                } else {
                    wire::EVENT_TRUNCATED
                };
                let success = if e == Ending::Success {
                    wire::EVENT_SUCCESS
                } else {
                    0
                };
                let fault = if e == Ending::Fault {
                    wire::EVENT_FAULT
                } else {
                    0
                };
                let placed = if info.placed { wire::EVENT_PLACED } else { 0 };
                kind | success | fault | placed
            });
            *t = EnvTick {
                env: env.id as u32,
                area: env.ground().code(),
                events,
                slot: chosen.slot.index() as u8,
                pos: p.pos.map(|v| v as f32),
                euler: p.euler.map(|v| v as f32),
                sin_pitch: p.euler[0].sin() as f32,
                reward: info.reward as f32,
                target: info.target.map(|v| v as f32),
                imu_euler: imu.map(|v| v as f32),
                imu_sin_pitch: imu[0].sin() as f32,
                command: env.action(),
                ..EnvTick::default()
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controllers::PolicyController;
    use crate::env::SharedTerrain;
    use crate::terrain::Terrain;
    use common::config::{AreaKind, SimConfig};
    use common::{Policy, PolicyLayout, Rng};

    /// The transitions of `ticks` steps of 2 flat and 2 rough envs under one stochastic
    /// policy, on `threads` sim threads.
    fn record(threads: usize, ticks: usize) -> Vec<Transition> {
        let mut cfg = SimConfig::default();
        cfg.spread(&[AreaKind::Flat, AreaKind::Rough], 2);
        cfg.threads = threads;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut fleet = Fleet::new(&cfg, &terrain, 9);
        let layout = PolicyLayout::new(OBS_DIM, &[16], ACT_DIM);
        let mut rng = Rng::new(4);
        let mut w: Vec<f32> = (0..layout.len())
            .map(|_| rng.range(-0.5, 0.5) as f32)
            .collect();
        // Observations unnormalised: mean 0, variance 1.
        w[layout.obs_mean()..layout.obs_mean() + OBS_DIM].fill(0.0);
        w[layout.obs_var()..layout.obs_var() + OBS_DIM].fill(1.0);
        let ctrl = PolicyController::new(Policy::new(layout, w, 10.0).expect("layout"), true, 9);
        let policies = PolicySet::new(PolicySlot::General, ctrl, 1);
        let mut driver = Driver::new(&fleet, 9);
        let mut chunk = Vec::new();
        for _ in 0..ticks {
            driver.tick(&mut fleet, &policies, &[], &[], &mut chunk);
        }
        chunk
    }

    #[test]
    fn each_env_samples_from_its_own_stream_whatever_the_thread_count() {
        let one = record(1, 60);
        assert_eq!(one.len(), 240);
        assert!(one.iter().all(|t| t.action.iter().all(|a| a.is_finite())));
        assert!(
            one == record(2, 60),
            "same seed, two threads: other transitions"
        );
        // Four envs, four streams: no two envs draw the same action noise.
        let first: Vec<[f32; ACT_DIM]> = one[..4].iter().map(|t| t.action).collect();
        for i in 0..4 {
            for j in i + 1..4 {
                assert_ne!(first[i], first[j], "envs {i} and {j}");
            }
        }
    }
}
