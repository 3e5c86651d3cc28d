//! `sim-proc serve`: the simulator inside a run. Acts with the newest policies from the
//! `policy/<slot>` services (DESIGN §5: per env the configured slot, or the one switching
//! picks from the estimator's classes), publishes every tick on `telemetry` and every T steps
//! a rollout chunk on `rollout`. In sync mode it waits after each chunk for the policies
//! learned from it (DESIGN §3); in async mode it never waits.

use crate::Fleet;
use crate::controllers::PolicyController;
use crate::driver::Driver;
use crate::env::SharedTerrain;
use crate::outputs::{TickFiles, TickOutputs};
use crate::switching::{PolicySet, Switcher};
use crate::terrain::Terrain;
use crate::waiting::{Nag, POLL};
use anyhow::Context;
use common::config::{Acting, LearnMode, PolicySlot};
use common::ipc::{self, Bus, Receiver, Sender};
use common::refusals::Refusals;
use common::wire::{PolicyHeader, RolloutHeader};
use common::{Config, Policy, Transition};
use std::time::{Duration, Instant};

/// How often the stepping loop looks for a shutdown and, in async mode, for new policies.
/// Each look is system calls (the control channel's socket, the signal check); a tick of one
/// env takes about 0.2 ms, and a look on every one of them cost more than publishing it.
const LOOK_EVERY: Duration = Duration::from_millis(1);

/// The policy services the sim listens to, one per slot (DESIGN §5), and what it holds.
struct Inbox {
    rx: Vec<(PolicySlot, Receiver<f32, PolicyHeader>)>,
    policies: Option<PolicySet>,
    /// Header of the policy each slot acts with; `learner` 0: none yet.
    heads: [PolicyHeader; PolicySlot::ALL.len()],
    seed: u64,
    /// Sample actions (training) or act with the mean (`sim.mean-actions`, evaluation).
    stochastic: bool,
    refused: Refusals,
}

impl Inbox {
    fn connect(bus: &Bus, seed: u64, stochastic: bool) -> anyhow::Result<Self> {
        let rx = PolicySlot::ALL
            .into_iter()
            .map(|s| Ok((s, bus.receiver(&ipc::POLICY, Some(s.name()))?)))
            .collect::<anyhow::Result<_>>()?;
        Ok(Self {
            rx,
            policies: None,
            heads: [PolicyHeader::default(); PolicySlot::ALL.len()],
            seed,
            stochastic,
            refused: Refusals::new("policy"),
        })
    }

    /// Applies the newest acceptable message of every slot; returns the headers applied.
    fn take(&mut self) -> anyhow::Result<Vec<(PolicySlot, PolicyHeader)>> {
        let mut got = Vec::new();
        for (slot, rx) in &self.rx {
            // DESIGN §2: the sim never acts with a policy it cannot trust; it keeps the one it
            // has. A refused message does not hide a good one that arrived before it: in async
            // mode a learner publishes again only after the sim's rollouts, so a first policy
            // lost behind a hostile one would stall the run.
            let mut newest = None;
            while let Some(sample) = rx.try_recv()? {
                let h = *sample.user_header();
                match h.refusal(*slot, sample.payload()) {
                    Some(kind) => self.refused.refuse(
                        kind,
                        &format!("slot {}, version {}", slot.name(), h.version),
                    ),
                    None => newest = Some((h, sample.payload().to_vec())),
                }
            }
            let Some((h, weights)) = newest else {
                continue;
            };
            let layout = h.layout();
            let fresh = |weights: &[f32]| -> anyhow::Result<PolicyController> {
                let policy = Policy::new(layout.clone(), weights.to_vec(), h.obs_clip)?;
                // The envs sample with the driver's streams; this one serves only
                // `Controller::act`, kept apart per slot.
                let seed = self.seed.wrapping_add(slot.index() as u64);
                Ok(PolicyController::new(policy, self.stochastic, seed))
            };
            match &mut self.policies {
                None => {
                    self.policies = Some(PolicySet::new(*slot, fresh(&weights)?, h.version));
                }
                Some(policies) => match policies.get_mut(*slot) {
                    Some(c) if c.policy.layout() == &layout => {
                        c.policy.set_weights(&weights)?;
                        policies.set_version(*slot, h.version);
                    }
                    _ => policies.insert(*slot, fresh(&weights)?, h.version),
                },
            }
            let was = self.heads[slot.index()].learner;
            if was != 0 && was != h.learner {
                tracing::info!(
                    slot = slot.name(),
                    from = was,
                    to = h.learner,
                    version = h.version,
                    updates = h.updates,
                    "a new learner took over"
                );
            }
            self.heads[slot.index()] = h;
            got.push((*slot, h));
        }
        Ok(got)
    }

    /// Sleeps until `slot`'s service signals or `timeout` passes.
    fn wait(&self, slot: PolicySlot, timeout: Duration) -> anyhow::Result<()> {
        if let Some((_, rx)) = self.rx.iter().find(|(s, _)| *s == slot) {
            rx.wait(timeout)?;
        }
        Ok(())
    }

    /// The version of the policy a `general` env acts with (for headers and logs).
    fn version(&self) -> u32 {
        self.policies
            .as_ref()
            .map_or(0, |p| p.version(p.resolve(PolicySlot::General)))
    }

    /// The newest env-step count of the policies received (a learner's is its checkpoint's).
    fn env_steps(&self) -> u64 {
        self.heads.iter().map(|h| h.env_steps).max().unwrap_or(0)
    }

    /// The slots that have learners, with the learner each has now.
    fn learners(&self) -> Vec<(PolicySlot, u32)> {
        PolicySlot::ALL
            .into_iter()
            .map(|s| (s, self.heads[s.index()].learner))
            .filter(|(_, l)| *l != 0)
            .collect()
    }
}

/// Sync mode (DESIGN §3): whether `h` answers the `sent` chunks — its learner has consumed
/// the last one, or it comes from a new learner (restarted or swapped), which may never have
/// received it; acting with a new learner's policy at once keeps the run going.
fn answers(h: &PolicyHeader, sent: u64, learner: u32) -> bool {
    h.chunks_seen >= sent || h.learner != learner
}

/// The sim's part in a run, as its command line gives it.
#[derive(Debug, Clone, Copy)]
pub struct RunPart<'a> {
    /// This sim's source id in its rollout chunks (`--source`).
    pub source: u32,
    /// Count env steps on from the learners' checkpoints (`--resume`).
    pub resume: bool,
    /// The files it writes as it steps.
    pub files: TickFiles<'a>,
}

/// Runs the simulator in run `run_id` until `run.total-steps` or a shutdown request; with
/// `sim.acting = "external"` a gym client acts instead ([`crate::external`]).
pub fn serve(cfg: &Config, run_id: &str, part: &RunPart) -> anyhow::Result<()> {
    let bus = Bus::connect(run_id, "sim")?;
    let mut outputs = TickOutputs::open(&bus, cfg, &part.files)?;
    let terrain = SharedTerrain::new(Terrain::build(&cfg.sim.terrain)?, cfg.sim.terrain.collider);
    if cfg.sim.acting == Acting::External {
        return crate::external::serve(cfg, &bus, &mut outputs, &terrain, part.source);
    }
    let control = bus.control_listener()?;
    let stop_requested = || bus.stop_requested(&control);
    let n = cfg.sim.num_envs();
    let t_steps = cfg.ppo.rollout_steps(n);
    let rollout_tx =
        bus.sender::<Transition, RolloutHeader>(&ipc::ROLLOUT, None, t_steps * n + n)?;
    // DESIGN §9: each sim host steps episodes of its own.
    let seed = common::Rng::source_seed(cfg.run.seed, part.source);
    let fleet = Fleet::new(&cfg.sim, &terrain, seed);
    let mut inbox = Inbox::connect(&bus, seed, !cfg.sim.mean_actions)?;
    let switcher = Switcher::new(cfg.sim.acting, |s| cfg.sim.dwell_leaving(s), n);
    tracing::info!(envs = n, rollout_steps = t_steps, mode = ?cfg.run.mode, acting = ?cfg.sim.acting, "waiting for the first policy");
    if !first_policy(&mut inbox, &stop_requested)? {
        return Ok(());
    }
    tracing::info!(learners = ?inbox.learners(), "first policy received");
    let driver = Driver::new(&fleet, seed);
    let chunk = Vec::with_capacity(t_steps * n + n);
    let env_steps = starting_steps(&inbox, part.resume);
    let started = Instant::now();
    let mut sim = Stepping {
        cfg,
        source: part.source,
        envs: n,
        rollout_steps: t_steps,
        fleet,
        driver,
        inbox,
        switcher,
        outputs,
        rollout_tx,
        chunk,
        env_steps,
        chunk_id: 0,
        started,
        looked: started,
    };
    sim.run(&stop_requested)?;
    sim.finish()
}

/// Waits until the inbox holds a first policy; false when the run asked to stop first.
fn first_policy(inbox: &mut Inbox, stop_requested: &dyn Fn() -> bool) -> anyhow::Result<bool> {
    let mut nag = Nag::new(Duration::from_secs(10));
    while inbox.take()?.is_empty() {
        if stop_requested() {
            return Ok(false);
        }
        inbox.wait(PolicySlot::General, POLL)?;
        if let Some(secs) = nag.due() {
            tracing::warn!(secs, "still no policy");
        }
    }
    Ok(true)
}

/// The env steps the run starts counting from. Resumed, the run goes on from the steps its
/// learners' checkpoints had learned from (what the sim stepped after them is collected
/// again); chunk ids start over, as they do for any learner that joins.
fn starting_steps(inbox: &Inbox, resume: bool) -> u64 {
    let env_steps = if resume { inbox.env_steps() } else { 0 };
    if resume {
        tracing::info!(
            env_steps,
            "resumed: counting on from the learners' checkpoints"
        );
    }
    env_steps
}

/// The sim acting with its learners' policies: its envs, the policies, what it publishes,
/// and how far the run has come.
struct Stepping<'a> {
    cfg: &'a Config,
    source: u32,
    envs: usize,
    rollout_steps: usize,
    fleet: Fleet,
    driver: Driver,
    inbox: Inbox,
    switcher: Switcher,
    outputs: TickOutputs,
    rollout_tx: Sender<Transition, RolloutHeader>,
    /// The rollout chunk being filled.
    chunk: Vec<Transition>,
    env_steps: u64,
    chunk_id: u64,
    started: Instant,
    /// When the stepping loop last looked for a shutdown and new policies.
    looked: Instant,
}

impl Stepping<'_> {
    /// Steps, sends and (in sync mode) waits for the answers to rollout chunks until
    /// `run.total-steps` or a shutdown request.
    fn run(&mut self, stop_requested: &dyn Fn() -> bool) -> anyhow::Result<()> {
        let total_steps = self.cfg.run.total_steps;
        while self.env_steps < total_steps {
            if !self.fill_chunk(stop_requested)? {
                return Ok(());
            }
            self.send_chunk()?;
            if self.cfg.run.mode == LearnMode::Sync
                && self.env_steps < total_steps
                && !self.wait_for_answers(stop_requested)?
            {
                return Ok(());
            }
        }
        Ok(())
    }

    /// Steps every env for one chunk's ticks, publishing each tick; false when the run asked
    /// to stop.
    fn fill_chunk(&mut self, stop_requested: &dyn Fn() -> bool) -> anyhow::Result<bool> {
        self.chunk.clear();
        for _ in 0..self.rollout_steps {
            let wanted = self.switcher.update(&self.outputs.classes);
            let policies = self.inbox.policies.as_ref().context("no policy")?;
            self.driver.tick(
                &mut self.fleet,
                policies,
                wanted,
                &self.outputs.classes,
                &mut self.chunk,
            );
            self.env_steps += self.envs as u64;
            self.outputs.publish(
                &self.fleet,
                &self.driver,
                self.env_steps,
                self.inbox.version(),
            )?;
            if self.looked.elapsed() >= LOOK_EVERY {
                self.looked = Instant::now();
                if stop_requested() {
                    return Ok(false);
                }
                if self.cfg.run.mode == LearnMode::Async {
                    self.inbox.take()?;
                }
            }
        }
        Ok(true)
    }

    /// Sends the filled chunk on `rollout` with its bootstrap observations.
    fn send_chunk(&mut self) -> anyhow::Result<()> {
        self.driver.bootstrap(&mut self.chunk);
        let header = RolloutHeader {
            chunk: self.chunk_id,
            env_steps: self.env_steps,
            steps: self.rollout_steps as u32,
            envs: self.envs as u32,
            source: self.source,
            _reserved: 0,
        };
        self.rollout_tx.send(header, &self.chunk)?;
        self.outputs.flush()?;
        self.chunk_id += 1;
        tracing::debug!(
            chunk = self.chunk_id,
            env_steps = self.env_steps,
            sps = self.env_steps as f64 / self.started.elapsed().as_secs_f64(),
            "rollout sent"
        );
        Ok(())
    }

    /// Sync mode (DESIGN §3: on-policy PPO): waits until every learner answered the chunks
    /// sent; false when the run asked to stop.
    fn wait_for_answers(&mut self, stop_requested: &dyn Fn() -> bool) -> anyhow::Result<bool> {
        let mut nag = Nag::new(Duration::from_secs(30));
        let mut pending = self.inbox.learners();
        loop {
            for (slot, h) in self.inbox.take()? {
                pending.retain(|(s, learner)| *s != slot || !answers(&h, self.chunk_id, *learner));
            }
            let Some(&(slot, _)) = pending.first() else {
                return Ok(true);
            };
            if stop_requested() {
                return Ok(false);
            }
            self.inbox.wait(slot, POLL)?;
            if let Some(secs) = nag.due() {
                tracing::warn!(
                    secs,
                    slot = slot.name(),
                    "sync mode: still waiting for the learner"
                );
            }
        }
    }

    /// Flushes the outputs and logs the run's closing line.
    fn finish(mut self) -> anyhow::Result<()> {
        self.outputs.finish()?;
        let secs = self.started.elapsed().as_secs_f64();
        tracing::info!(
            env_steps = self.env_steps,
            episodes = self.driver.episodes.episodes,
            successes = self.driver.episodes.successes,
            policy_version = self.inbox.version(),
            env_steps_per_s = self.env_steps as f64 / secs,
            refused = %self.inbox.refused.summary(),
            "sim done"
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sync_sim_waits_for_its_chunk_or_a_new_learner() {
        let h = |chunks_seen, learner| PolicyHeader {
            chunks_seen,
            learner,
            ..PolicyHeader::default()
        };
        // Three chunks sent (ids 0..=2), acting with learner 7's policy.
        assert!(!answers(&h(2, 7), 3, 7), "learned from chunk 1 only");
        assert!(answers(&h(3, 7), 3, 7), "learned from chunk 2");
        assert!(
            answers(&h(0, 8), 3, 7),
            "a restarted learner's first policy"
        );
    }
}
