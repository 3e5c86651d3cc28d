//! `sim.acting = "external"`: a gym client acts (the Python package's `lavatube.gym`).
//!
//! Each request on `gym/act` (a reset, a step with every env's actions, or a close) gets one
//! answer on `gym/step`: every env's observation, reward and episode flags, an ended episode
//! already replaced by the next (Gymnasium's same-step autoreset). Telemetry, the track and
//! the estimator run as they do under a policy; no rollouts are published. A client silent
//! for `sim.external.timeout-s` is given up on: the sim ends with an error naming why, or,
//! with `sim.external.stay-up`, waits for the next client.

use crate::Fleet;
use crate::driver::Driver;
use crate::env::SharedTerrain;
use crate::outputs::TickOutputs;
use crate::task::Ending;
use crate::waiting::{Nag, POLL};
use common::config::SimConfig;
use common::ipc::{self, Bus};
use common::refusals::Refusals;
use common::wire::{
    GYM_CLOSE, GYM_OK, GYM_READY, GYM_REFUSED, GYM_RESET, GYM_SEEDED, GYM_STEP, GymActHeader,
    GymEnvStep, GymStepHeader,
};
use common::{ACT_DIM, Config, OBS_DIM, Rng};
use std::time::{Duration, Instant};

/// What a request did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Reset,
    Stepped,
    Closed,
    Refused,
}

/// The envs a gym client drives, and where the client stands (reset or not).
pub struct GymEnvs {
    pub fleet: Fleet,
    pub driver: Driver,
    cfg: SimConfig,
    terrain: SharedTerrain,
    /// The sim's source id, mixed into a reset's seed as into the run seed (DESIGN §9).
    source: u32,
    /// Whether the client has reset since it arrived; a step before that is refused.
    reset: bool,
    /// Decision steps since the client's last reset, and env steps in all.
    tick: u64,
    env_steps: u64,
    answer: Vec<GymEnvStep>,
    actions: Vec<[f32; ACT_DIM]>,
    pub refused: Refusals,
}

impl GymEnvs {
    /// The envs of `cfg` seeded as a run with `seed` seeds them.
    pub fn new(cfg: &SimConfig, terrain: &SharedTerrain, seed: u64, source: u32) -> Self {
        let seed = Rng::source_seed(seed, source);
        let fleet = Fleet::new(cfg, terrain, seed);
        let n = fleet.len();
        Self {
            driver: Driver::new(&fleet, seed),
            fleet,
            cfg: cfg.clone(),
            terrain: terrain.clone(),
            source,
            reset: false,
            tick: 0,
            env_steps: 0,
            answer: vec![GymEnvStep::default(); n],
            actions: vec![[0.0; ACT_DIM]; n],
            refused: Refusals::new("gym request"),
        }
    }

    /// Carries out one request (`actions`: its slice) and says what it did; the envs after
    /// it are in [`answer`](Self::answer).
    pub fn handle(&mut self, h: &GymActHeader, actions: &[f32]) -> (GymStepHeader, Outcome) {
        let n = self.fleet.len();
        let outcome = match h.command {
            GYM_RESET => {
                if h.flags & GYM_SEEDED != 0 {
                    let seed = Rng::source_seed(h.seed, self.source);
                    self.fleet = Fleet::new(&self.cfg, &self.terrain, seed);
                } else {
                    self.fleet.restart();
                }
                self.driver.restart(&self.fleet);
                (self.reset, self.tick) = (true, 0);
                Outcome::Reset
            }
            GYM_STEP if !self.reset => self.refuse("step before reset", "send a reset first"),
            GYM_STEP if actions.len() != n * ACT_DIM => self.refuse(
                "wrong action count",
                &format!("{} values for {n} envs × {ACT_DIM}", actions.len()),
            ),
            GYM_STEP => {
                for (a, pair) in self.actions.iter_mut().zip(actions.chunks_exact(ACT_DIM)) {
                    a.copy_from_slice(pair);
                }
                self.driver.step_with(&mut self.fleet, &self.actions);
                self.tick += 1;
                self.env_steps += n as u64;
                Outcome::Stepped
            }
            GYM_CLOSE => {
                self.leave();
                Outcome::Closed
            }
            other => self.refuse("unknown command", &other.to_string()),
        };
        if matches!(outcome, Outcome::Reset | Outcome::Stepped) {
            self.fill_answer();
        }
        let status = if outcome == Outcome::Refused {
            GYM_REFUSED
        } else {
            GYM_OK
        };
        (self.header(h.request, h.command, status), outcome)
    }

    /// The header of an answer to `request`.
    pub fn header(&self, request: u64, command: u32, status: u32) -> GymStepHeader {
        GymStepHeader {
            request,
            tick: self.tick,
            env_steps: self.env_steps,
            envs: self.fleet.len() as u32,
            command,
            status,
            action_limit: self.cfg.robot.action_limit as f32,
        }
    }

    /// Every env after the last reset or step.
    pub fn answer(&self) -> &[GymEnvStep] {
        &self.answer
    }

    /// The client is gone: the next one must reset before it steps.
    pub fn leave(&mut self) {
        self.reset = false;
    }

    fn refuse(&mut self, kind: &'static str, detail: &str) -> Outcome {
        self.refused.refuse(kind, detail);
        Outcome::Refused
    }

    fn fill_answer(&mut self) {
        let d = &self.driver;
        for (i, (a, env)) in self.answer.iter_mut().zip(&self.fleet.envs).enumerate() {
            let (info, end) = (&d.infos[i], d.infos[i].ending);
            *a = GymEnvStep {
                obs: d.obs[i],
                final_obs: if end.is_some() {
                    info.final_obs
                } else {
                    [0.0; OBS_DIM]
                },
                reward: info.reward as f32,
                episode_steps: info.episode_steps,
                terminated: u8::from(end.is_some_and(Ending::terminated)),
                truncated: u8::from(end.is_some_and(Ending::truncated)),
                success: u8::from(end == Some(Ending::Success)),
                area: env.ground().code(),
                env: i as u32,
            };
        }
    }
}

/// Serves gym clients in the run `bus` belongs to until the launcher stops the run, or the
/// client closes or is given up on (without `sim.external.stay-up`).
pub fn serve(
    cfg: &Config,
    bus: &Bus,
    outputs: &mut TickOutputs,
    terrain: &SharedTerrain,
    source: u32,
) -> anyhow::Result<()> {
    let n = cfg.sim.num_envs();
    let control = bus.control_listener()?;
    let requests = bus.receiver(&ipc::GYM_ACT, None)?;
    let answers = bus.sender(&ipc::GYM_STEP, None, n)?;
    let ext = &cfg.sim.external;
    let timeout = Duration::from_secs_f64(ext.timeout_s);
    let mut gym = GymEnvs::new(&cfg.sim, terrain, cfg.run.seed, source);
    tracing::info!(
        envs = n,
        timeout_s = ext.timeout_s,
        stay_up = ext.stay_up,
        "waiting for a gym client"
    );
    answers.send(gym.header(0, GYM_READY, GYM_OK), &[])?;
    // When the client was last heard from; none between clients with stay-up (no deadline).
    let mut heard = Some(Instant::now());
    let mut nag = Nag::new(Duration::from_secs(60));
    while !bus.stop_requested(&control) {
        let Some(sample) = requests.try_recv()? else {
            if heard.is_some_and(|t| t.elapsed() >= timeout) {
                let why = format!(
                    "no request from the gym client for {} s (sim.external.timeout-s): it died or stalled",
                    ext.timeout_s
                );
                if !ext.stay_up {
                    outputs.finish()?;
                    anyhow::bail!(why);
                }
                tracing::error!("{why}; waiting for the next client (sim.external.stay-up)");
                gym.leave();
                (heard, nag) = (None, Nag::new(Duration::from_secs(60)));
            }
            if heard.is_none()
                && let Some(secs) = nag.due()
            {
                tracing::info!(secs, "still waiting for a gym client");
            }
            outputs.flush()?;
            // A client that connects gets the newest answer (history) only once the sender
            // acts: it learns the envs and the action limit from it.
            answers.update_connections()?;
            requests.wait(POLL)?;
            continue;
        };
        heard = Some(Instant::now());
        let (header, outcome) = gym.handle(sample.user_header(), sample.payload());
        drop(sample);
        if outcome == Outcome::Stepped {
            outputs.publish(&gym.fleet, &gym.driver, header.env_steps, 0)?;
        }
        let answer = match outcome {
            Outcome::Reset | Outcome::Stepped => gym.answer(),
            Outcome::Closed | Outcome::Refused => &[],
        };
        answers.send(header, answer)?;
        if outcome == Outcome::Closed {
            if !ext.stay_up {
                break;
            }
            tracing::info!("the gym client closed; waiting for the next (sim.external.stay-up)");
            (heard, nag) = (None, Nag::new(Duration::from_secs(60)));
        }
    }
    outputs.finish()?;
    tracing::info!(
        env_steps = gym.env_steps,
        episodes = gym.driver.episodes.episodes,
        successes = gym.driver.episodes.successes,
        refused = %gym.refused.summary(),
        "sim done"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::StepInfo;
    use crate::terrain::Terrain;

    fn request(request: u64, command: u32, seed: Option<u64>) -> GymActHeader {
        GymActHeader {
            request,
            seed: seed.unwrap_or(0),
            command,
            flags: if seed.is_some() { GYM_SEEDED } else { 0 },
        }
    }

    #[test]
    fn a_gym_client_steps_the_envs_as_the_sim_alone_does_with_same_step_autoreset() {
        let mut cfg = SimConfig {
            envs: [(common::AreaKind::Flat, 2), (common::AreaKind::Rough, 1)].into(),
            threads: 1,
            ..SimConfig::default()
        };
        // Env 0 stands still and stalls every 10 steps: endings to check.
        cfg.task.stall_steps = 10;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut gym = GymEnvs::new(&cfg, &terrain, 1, 0);
        let (h, o) = gym.handle(&request(1, GYM_STEP, None), &[0.0; 6]);
        assert_eq!((o, h.status, h.request), (Outcome::Refused, GYM_REFUSED, 1));

        let (h, o) = gym.handle(&request(2, GYM_RESET, Some(7)), &[]);
        assert_eq!(
            (o, h.status, h.tick, h.envs),
            (Outcome::Reset, GYM_OK, 0, 3)
        );
        assert_eq!(h.action_limit, 3.0, "SPEC S2's default bound");
        let mut alone = Fleet::new(&cfg, &terrain, 7);
        let mut obs = vec![[0.0; OBS_DIM]; 3];
        alone.observe(&mut obs);
        assert!(gym.answer().iter().zip(&obs).all(|(a, o)| a.obs == *o));

        let mut infos = vec![StepInfo::default(); 3];
        let mut ended = 0;
        for t in 0..25u64 {
            let turn = (t as f32 * 0.3).sin() * 2.0;
            let actions = [[0.0, 0.0], [3.0, 3.0 - turn], [2.0 + turn, 2.0]];
            let flat: Vec<f32> = actions.iter().flatten().copied().collect();
            let (h, o) = gym.handle(&request(3 + t, GYM_STEP, None), &flat);
            assert_eq!(
                (o, h.tick, h.env_steps),
                (Outcome::Stepped, t + 1, 3 * (t + 1))
            );
            alone.step(&actions, &mut infos, &mut obs);
            for (i, a) in gym.answer().iter().enumerate() {
                let end = infos[i].ending;
                assert_eq!(a.obs, obs[i], "tick {t} env {i}");
                assert_eq!(a.reward, infos[i].reward as f32);
                assert_eq!(a.terminated == 1, end.is_some_and(Ending::terminated));
                assert_eq!(a.truncated == 1, end.is_some_and(Ending::truncated));
                if end.is_some() {
                    assert_eq!(a.final_obs, infos[i].final_obs);
                    assert_ne!(a.final_obs, a.obs, "the next episode's first observation");
                    ended += 1;
                } else {
                    assert_eq!(a.final_obs, [0.0; OBS_DIM]);
                }
            }
        }
        assert!(ended >= 2, "env 0 stalled at steps 10 and 20: {ended}");

        let before = gym.answer()[1].obs;
        let (h, o) = gym.handle(&request(40, GYM_STEP, None), &[0.0; 5]);
        assert_eq!((o, h.tick), (Outcome::Refused, 25), "nothing moved");
        assert_eq!(gym.refused.count("wrong action count"), 1);
        let (h, o) = gym.handle(&request(41, GYM_RESET, None), &[]);
        assert_eq!((o, h.tick), (Outcome::Reset, 0));
        assert_ne!(gym.answer()[1].obs, before, "a new episode from a new pose");
        assert_eq!(
            gym.handle(&request(42, GYM_CLOSE, None), &[]).1,
            Outcome::Closed
        );
        let (_, o) = gym.handle(&request(43, GYM_STEP, None), &[0.0; 6]);
        assert_eq!(o, Outcome::Refused, "the next client resets first");
        assert_eq!(gym.handle(&request(44, 9, None), &[]).1, Outcome::Refused);
    }
}
