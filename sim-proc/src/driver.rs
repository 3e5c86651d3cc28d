//! Acting and recording: one decision step of every env under a policy, appended to a rollout
//! chunk as [`Transition`]s. Shared by `serve` and by in-process training loops, so both
//! produce the same transitions from the same seed.

use crate::Fleet;
use crate::env::StepInfo;
use crate::switching::PolicySet;
use crate::task::Ending;
use common::config::PolicySlot;
use common::episode::EpisodeStats;
use common::wire::{self, EnvTick};
use common::{ACT_DIM, OBS_DIM, Transition};

/// Per-env buffers of the acting loop.
pub struct Driver {
    /// Each env's current observation.
    pub obs: Vec<[f32; OBS_DIM]>,
    next_obs: Vec<[f32; OBS_DIM]>,
    actions: Vec<[f32; ACT_DIM]>,
    logprobs: Vec<f32>,
    /// The slot and version that acted in the last step, per env.
    acted: Vec<(PolicySlot, u32)>,
    /// What the last step produced, per env.
    pub infos: Vec<StepInfo>,
    /// Every episode ended so far, counted here where it ends.
    pub episodes: EpisodeStats,
}

impl Driver {
    pub fn new(fleet: &Fleet) -> Self {
        let n = fleet.len();
        let mut obs = vec![[0.0f32; OBS_DIM]; n];
        fleet.observe(&mut obs);
        Self {
            next_obs: obs.clone(),
            obs,
            actions: vec![[0.0; ACT_DIM]; n],
            logprobs: vec![0.0; n],
            acted: vec![(PolicySlot::General, 0); n],
            infos: vec![StepInfo::default(); n],
            episodes: EpisodeStats::default(),
        }
    }

    /// Samples every env's action from `policies` (env `i` asks for slot `wanted[i]`), steps
    /// the fleet and appends one transition per env to `chunk`. `classes` holds the
    /// estimator's current class per env.
    pub fn tick(
        &mut self,
        fleet: &mut Fleet,
        policies: &mut PolicySet,
        wanted: &[PolicySlot],
        classes: &[u8],
        chunk: &mut Vec<Transition>,
    ) {
        for (i, o) in self.obs.iter().enumerate() {
            let w = wanted.get(i).copied().unwrap_or(PolicySlot::General);
            let (slot, version, action, logprob) = policies.sample(w, o);
            (self.actions[i], self.logprobs[i], self.acted[i]) = (action, logprob, (slot, version));
        }
        fleet.step(&self.actions, &mut self.infos, &mut self.next_obs);
        self.count_endings();
        for (i, env) in fleet.envs.iter().enumerate() {
            let info = &self.infos[i];
            let end = info.ending;
            chunk.push(Transition {
                obs: self.obs[i],
                action: self.actions[i],
                final_obs: info.final_obs,
                logprob: self.logprobs[i],
                reward: info.reward as f32,
                policy_version: self.acted[i].1,
                slot: self.acted[i].0.index() as u8,
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
        self.actions.copy_from_slice(actions);
        fleet.step(&self.actions, &mut self.infos, &mut self.next_obs);
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
        for (((t, env), info), acted) in out
            .iter_mut()
            .zip(&fleet.envs)
            .zip(&self.infos)
            .zip(&self.acted)
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
                kind | success | fault
            });
            *t = EnvTick {
                env: env.id as u32,
                area: env.ground().code(),
                events,
                slot: acted.0.index() as u8,
                pos: p.pos.map(|v| v as f32),
                euler: p.euler.map(|v| v as f32),
                sin_pitch: p.euler[0].sin() as f32,
                reward: info.reward as f32,
                target: info.target.map(|v| v as f32),
                imu_euler: imu.map(|v| v as f32),
                imu_sin_pitch: imu[0].sin() as f32,
                ..EnvTick::default()
            };
        }
    }
}
