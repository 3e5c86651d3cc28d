//! Controllers that drive envs without a learner: random, go-to-target, actions replayed from
//! a file, and a policy given as a flat weight vector (evaluated by `common`'s plain-Rust
//! forward; no burn here).
//! All act from the SPEC S5 observation alone.

use crate::env::StepInfo;
use crate::{Fleet, SimError};
use common::policy::Scratch;
use common::{ACT_DIM, OBS_DIM, Policy, Rng};
use std::path::Path;

/// Picks one env's wheel commands from its observation.
pub trait Controller: Send {
    fn act(&mut self, env: usize, obs: &[f32; OBS_DIM]) -> [f32; ACT_DIM];

    /// Steps `fleet` once with the actions for `obs`, writing each env's action, step info
    /// and next observation: by default every env's action first, in order, on this thread.
    fn step(&mut self, fleet: &mut Fleet, obs: &[[f32; OBS_DIM]], out: StepOut<'_>) {
        for (i, a) in out.actions.iter_mut().enumerate() {
            *a = self.act(i, &obs[i]);
        }
        fleet.step(out.actions, out.infos, out.next_obs);
    }
}

/// Where [`Controller::step`] writes, one entry per env.
pub struct StepOut<'a> {
    pub actions: &'a mut [[f32; ACT_DIM]],
    pub infos: &'a mut [StepInfo],
    pub next_obs: &'a mut [[f32; OBS_DIM]],
}

/// Uniform random wheel commands, each held for `hold` ticks (so the robot actually goes
/// somewhere rather than jittering in place).
pub struct RandomController {
    limit: f32,
    hold: u32,
    rng: Rng,
    held: Vec<([f32; ACT_DIM], u32)>,
}

impl RandomController {
    pub fn new(limit: f64, hold: u32, seed: u64) -> Self {
        Self {
            limit: limit as f32,
            hold: hold.max(1),
            rng: Rng::derive(seed, 0x5EED),
            held: Vec::new(),
        }
    }
}

impl Controller for RandomController {
    fn act(&mut self, env: usize, _obs: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
        if self.held.len() <= env {
            self.held.resize(env + 1, ([0.0; ACT_DIM], 0));
        }
        let (cmd, left) = &mut self.held[env];
        if *left == 0 {
            let l = f64::from(self.limit);
            *cmd = [self.rng.range(-l, l) as f32, self.rng.range(-l, l) as f32];
            *left = self.hold;
        }
        *left -= 1;
        *cmd
    }
}

/// Proportional steering toward the target: full speed ahead, scaled down while the heading
/// error is large; the difference between the wheels is proportional to the error.
pub struct GoToController {
    pub limit: f32,
    /// rad/s of wheel-speed difference per radian of heading error.
    pub gain: f32,
}

impl GoToController {
    pub fn new(limit: f64) -> Self {
        Self {
            limit: limit as f32,
            gain: 4.0,
        }
    }
}

impl Controller for GoToController {
    fn act(&mut self, _env: usize, obs: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
        // Body frame: +X is the robot's left, +Z its front (obs[0], obs[2]).
        let heading_error = obs[0].atan2(obs[2]);
        let forward = self.limit * heading_error.cos().max(0.0);
        let turn = (self.gain * heading_error).clamp(-self.limit, self.limit);
        [
            (forward - turn).clamp(-self.limit, self.limit),
            (forward + turn).clamp(-self.limit, self.limit),
        ]
    }
}

/// Wheel commands read back from a CSV (`tick,env,left,right`, one row per env and tick, in
/// that order), e.g. what a gym client sent, replayed exactly.
pub struct ReplayController {
    actions: Vec<[f32; ACT_DIM]>,
    envs: usize,
    /// The next tick of each env.
    next: Vec<usize>,
}

impl ReplayController {
    /// Reads `path` for `envs` envs; an error names the line that is wrong.
    pub fn load(path: &Path, envs: usize) -> Result<Self, SimError> {
        let bad = |reason: String| SimError::Actions {
            path: path.to_path_buf(),
            reason,
        };
        let mut reader = csv::Reader::from_path(path).map_err(|e| bad(e.to_string()))?;
        let header = reader.headers().map_err(|e| bad(e.to_string()))?;
        if header != vec!["tick", "env", "left", "right"] {
            return Err(bad(format!(
                "header is {header:?}; expected tick,env,left,right"
            )));
        }
        let mut actions = Vec::new();
        for (i, record) in reader.records().enumerate() {
            let record = record.map_err(|e| bad(e.to_string()))?;
            let line = i + 2;
            let field = |k: usize| record.get(k).unwrap_or_default();
            let want = (i / envs, i % envs);
            if (field(0).parse::<usize>(), field(1).parse::<usize>()) != (Ok(want.0), Ok(want.1)) {
                return Err(bad(format!(
                    "line {line}: tick {:?} env {:?}, expected tick {} env {} (rows go env by env, tick by tick)",
                    field(0),
                    field(1),
                    want.0,
                    want.1
                )));
            }
            let wheel = |k: usize| {
                field(k)
                    .parse::<f32>()
                    .map_err(|_| bad(format!("line {line}: {:?} is not a number", field(k))))
            };
            actions.push([wheel(2)?, wheel(3)?]);
        }
        if actions.is_empty() || actions.len() % envs != 0 {
            return Err(bad(format!(
                "{} rows are not whole ticks of {envs} envs",
                actions.len()
            )));
        }
        Ok(Self {
            actions,
            envs,
            next: vec![0; envs],
        })
    }

    /// Ticks the file holds.
    pub fn ticks(&self) -> u64 {
        (self.actions.len() / self.envs) as u64
    }
}

impl Controller for ReplayController {
    fn act(&mut self, env: usize, _obs: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
        let tick = self.next[env];
        self.next[env] += 1;
        self.actions
            .get(tick * self.envs + env)
            .copied()
            .unwrap_or([0.0; ACT_DIM])
    }
}

/// A policy network: its mean action (deterministic), or a sample from its Gaussian.
pub struct PolicyController {
    pub policy: Policy,
    /// Sample from the policy's Gaussian rather than act with its mean.
    pub stochastic: bool,
    seed: u64,
    /// Env `i`'s [`Actor::for_env`], made when env `i` first acts.
    actors: Vec<Actor>,
}

impl PolicyController {
    pub fn new(policy: Policy, stochastic: bool, seed: u64) -> Self {
        Self {
            policy,
            stochastic,
            seed,
            actors: Vec::new(),
        }
    }

    /// The unclipped action for `obs` and its log-probability under the policy (the sim
    /// clips it), drawn with `actor`'s stream. Reads the policy only, so envs act in parallel.
    pub fn sample(&self, obs: &[f32; OBS_DIM], actor: &mut Actor) -> ([f32; ACT_DIM], f32) {
        actor.sample(&self.policy, self.stochastic, obs)
    }

    fn actors_for(&mut self, envs: usize) {
        let seed = self.seed;
        let have = self.actors.len();
        self.actors
            .extend((have..envs).map(|i| Actor::for_env(seed, i)));
    }
}

impl Controller for PolicyController {
    fn act(&mut self, env: usize, obs: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
        self.actors_for(env + 1);
        self.actors[env]
            .sample(&self.policy, self.stochastic, obs)
            .0
    }

    /// Each env samples on the thread that steps it, as in a run ([`crate::driver::Driver`]).
    fn step(&mut self, fleet: &mut Fleet, obs: &[[f32; OBS_DIM]], out: StepOut<'_>) {
        self.actors_for(fleet.len());
        let (policy, stochastic) = (&self.policy, self.stochastic);
        fleet.decide_and_step(
            self.actors.iter_mut().zip(out.actions.iter_mut()),
            &|i, (actor, action)| {
                *action = actor.sample(policy, stochastic, &obs[i]).0;
                *action
            },
            out.infos,
            out.next_obs,
        );
    }
}

/// Where env `i`'s sampling stream sits among those a seed derives: `ACTOR_STREAMS + i`.
const ACTOR_STREAMS: u64 = 0xAC7_0000;

/// One env's means to act: its own random stream and the network's scratch space, so the
/// envs of a fleet sample in parallel and each draws the same numbers whichever thread
/// serves it.
pub struct Actor {
    rng: Rng,
    scratch: Scratch,
}

impl Actor {
    /// Env `i`'s actor under the sim seed `seed`.
    pub fn for_env(seed: u64, i: usize) -> Self {
        Self {
            rng: Rng::derive(seed, ACTOR_STREAMS + i as u64),
            scratch: Scratch::default(),
        }
    }

    fn sample(
        &mut self,
        policy: &Policy,
        stochastic: bool,
        obs: &[f32; OBS_DIM],
    ) -> ([f32; ACT_DIM], f32) {
        let mut action = [0.0; ACT_DIM];
        let rng = stochastic.then_some(&mut self.rng);
        let lp = policy.sample(obs, rng, &mut action, &mut self.scratch);
        (action, lp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn goto_steers_toward_the_target() {
        let mut c = GoToController::new(3.0);
        let mut obs = [0.0; OBS_DIM];
        obs[2] = 0.3; // straight ahead
        assert_eq!(c.act(0, &obs), [3.0, 3.0]);
        obs[0] = 0.3; // 45° to the left: right wheel faster
        let [l, r] = c.act(0, &obs);
        assert!(r > l, "{l} {r}");
        obs[2] = -0.3; // behind: turn in place, no forward drive
        let [l, r] = c.act(0, &obs);
        assert!((l + r).abs() < 1e-6 && r > 0.0);
    }

    #[test]
    fn replayed_actions_come_back_per_env_and_tick_and_bad_files_name_their_line() {
        let dir = tempfile::tempdir().expect("tmp");
        let file = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).expect("write");
            p
        };
        let good = file(
            "a.csv",
            "tick,env,left,right\n0,0,1.5,-2\n0,1,0.25,3\n1,0,NaN,0\n1,1,-1,1\n",
        );
        let mut c = ReplayController::load(&good, 2).expect("valid");
        let obs = [0.0; OBS_DIM];
        assert_eq!(c.ticks(), 2);
        assert_eq!(c.act(0, &obs), [1.5, -2.0]);
        assert_eq!(c.act(1, &obs), [0.25, 3.0]);
        assert!(c.act(0, &obs)[0].is_nan());
        assert_eq!(c.act(1, &obs), [-1.0, 1.0]);
        assert_eq!(c.act(1, &obs), [0.0, 0.0], "past the file's end");
        let err = |name, text| {
            ReplayController::load(&file(name, text), 2)
                .err()
                .expect("refused")
                .to_string()
        };
        assert!(err("order.csv", "tick,env,left,right\n0,1,0,0\n").contains("line 2"));
        assert!(err("nan.csv", "tick,env,left,right\n0,0,x,0\n").contains("\"x\" is not a number"));
        assert!(err("part.csv", "tick,env,left,right\n0,0,0,0\n").contains("whole ticks"));
        assert!(err("head.csv", "t,e,l,r\n").contains("expected tick,env,left,right"));
    }

    #[test]
    fn random_commands_are_held_and_bounded() {
        let mut c = RandomController::new(3.0, 5, 1);
        let obs = [0.0; OBS_DIM];
        let first = c.act(0, &obs);
        for _ in 0..4 {
            assert_eq!(c.act(0, &obs), first);
        }
        let next = c.act(0, &obs);
        assert_ne!(next, first);
        assert!(next.iter().all(|a| a.abs() <= 3.0));
    }
}
