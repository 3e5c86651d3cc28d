//! `sim-proc serve`: the simulator inside a run. Acts with the newest policy from the
//! `policy` service, publishes every tick on `telemetry` and every T steps a rollout chunk on
//! `rollout`, and reads terrain estimates. In sync mode it waits after each chunk for the
//! policy learned from it (DESIGN §3); in async mode it never waits.

use crate::Batch;
use crate::actor::Actor;
use crate::controllers::PolicyController;
use crate::env::SharedTerrain;
use crate::terrain::Terrain;
use anyhow::Context;
use common::config::LearnMode;
use common::ipc::{self, Bus, Receiver};
use common::wire::{
    self, EnvTick, PolicyHeader, RolloutHeader, TerrainEstimate, TerrainHeader, TickHeader,
};
use common::{ACT_DIM, Config, OBS_DIM, Policy, Transition};
use std::time::{Duration, Instant};

/// How long to sleep between checks while waiting for a policy.
const POLL: Duration = Duration::from_millis(100);

/// Paces "still waiting" warnings: due once per `every` of waiting.
struct Nag {
    since: Instant,
    next: Duration,
    every: Duration,
}

impl Nag {
    fn new(every: Duration) -> Self {
        Self {
            since: Instant::now(),
            next: every,
            every,
        }
    }

    /// Seconds waited so far, when a warning is due.
    fn due(&mut self) -> Option<u64> {
        let waited = self.since.elapsed();
        (waited >= self.next).then(|| {
            self.next += self.every;
            waited.as_secs()
        })
    }
}

/// Applies the newest policy message, if any. Returns whether the weights changed.
fn take_policy(
    rx: &Receiver<f32, PolicyHeader>,
    ctrl: &mut Option<PolicyController>,
    version: &mut u32,
    seed: u64,
) -> anyhow::Result<bool> {
    let Some(sample) = rx.latest()? else {
        return Ok(false);
    };
    let h = *sample.user_header();
    let layout = h.layout();
    if layout.obs_dim != OBS_DIM || layout.act_dim != ACT_DIM {
        tracing::error!(
            ?layout,
            "policy with the wrong shape refused; keeping the current one"
        );
        return Ok(false);
    }
    match ctrl {
        Some(c) if c.policy.layout() == &layout => c.policy.set_weights(sample.payload())?,
        _ => {
            let policy = Policy::new(layout, sample.payload().to_vec(), h.obs_clip)?;
            *ctrl = Some(PolicyController::new(policy, true, seed));
        }
    }
    *version = h.version;
    Ok(true)
}

/// Runs the simulator in run `run_id` until `run.total-steps` or a shutdown request.
pub fn serve(cfg: &Config, run_id: &str) -> anyhow::Result<()> {
    let n = cfg.sim.num_envs();
    let t_steps = cfg.ppo.rollout_steps(n);
    let bus = Bus::connect(run_id, "sim")?;
    let control = bus.control_listener()?;
    let policy_rx = bus.receiver::<f32, PolicyHeader>(&ipc::POLICY, Some("general"))?;
    let terrain_rx = bus.receiver::<TerrainEstimate, TerrainHeader>(&ipc::TERRAIN, None)?;
    let rollout_tx =
        bus.sender::<Transition, RolloutHeader>(&ipc::ROLLOUT, None, t_steps * n + n)?;
    let tele_tx = bus.sender::<EnvTick, TickHeader>(&ipc::TELEMETRY, None, n)?;

    let terrain = SharedTerrain::new(Terrain::build(&cfg.sim.terrain)?);
    let mut batch = Batch::new(&cfg.sim, &terrain, cfg.run.seed);
    let mut ctrl: Option<PolicyController> = None;
    let mut version = 0u32;
    tracing::info!(envs = n, rollout_steps = t_steps, mode = ?cfg.run.mode, "waiting for the first policy");
    let mut nag = Nag::new(Duration::from_secs(10));
    while !take_policy(&policy_rx, &mut ctrl, &mut version, cfg.run.seed)? {
        if bus.stop_requested(&control) {
            return Ok(());
        }
        policy_rx.wait(POLL)?;
        if let Some(secs) = nag.due() {
            tracing::warn!(secs, "still no policy");
        }
    }
    tracing::info!(version, "first policy received");

    let mut actor = Actor::new(&batch);
    let mut classes = vec![wire::CLASS_UNKNOWN; n];
    let mut ticks = vec![EnvTick::default(); n];
    let mut chunk = Vec::with_capacity(t_steps * n + n);
    let (mut env_steps, mut chunk_id, mut tick) = (0u64, 0u64, 0u64);
    let started = Instant::now();
    'run: while env_steps < cfg.run.total_steps {
        let chunk_version = version;
        chunk.clear();
        for _ in 0..t_steps {
            let c = ctrl.as_mut().context("no policy")?;
            actor.tick(&mut batch, c, version, &classes, &mut chunk);
            if let Some(est) = terrain_rx.latest()? {
                for e in est.payload().iter().filter(|e| (e.env as usize) < n) {
                    classes[e.env as usize] = e.class;
                }
            }
            actor.env_ticks(&batch, &mut ticks);
            env_steps += n as u64;
            let header = TickHeader {
                tick,
                env_steps,
                policy_version: version,
                envs: n as u32,
                episodes: actor.episodes,
                successes: actor.successes,
            };
            tele_tx.send(header, &ticks)?;
            tick += 1;
            if bus.stop_requested(&control) {
                break 'run;
            }
            if cfg.run.mode == LearnMode::Async {
                take_policy(&policy_rx, &mut ctrl, &mut version, cfg.run.seed)?;
            }
        }
        actor.bootstrap(&mut chunk);
        let header = RolloutHeader {
            chunk: chunk_id,
            env_steps,
            policy_version: chunk_version,
            steps: t_steps as u32,
            envs: n as u32,
            slot: 0,
        };
        rollout_tx.send(header, &chunk)?;
        chunk_id += 1;
        tracing::debug!(
            chunk = chunk_id,
            env_steps,
            sps = env_steps as f64 / started.elapsed().as_secs_f64(),
            "rollout sent"
        );
        if cfg.run.mode == LearnMode::Sync && env_steps < cfg.run.total_steps {
            // DESIGN §3: on-policy PPO; wait for the weights learned from this chunk.
            let mut nag = Nag::new(Duration::from_secs(30));
            while version <= chunk_version {
                if bus.stop_requested(&control) {
                    break 'run;
                }
                policy_rx.wait(POLL)?;
                take_policy(&policy_rx, &mut ctrl, &mut version, cfg.run.seed)?;
                if let Some(secs) = nag.due() {
                    tracing::warn!(secs, version, "sync mode: still waiting for the learner");
                }
            }
        }
    }
    let secs = started.elapsed().as_secs_f64();
    tracing::info!(
        env_steps,
        episodes = actor.episodes,
        successes = actor.successes,
        policy_version = version,
        env_steps_per_s = env_steps as f64 / secs,
        "sim done"
    );
    Ok(())
}
