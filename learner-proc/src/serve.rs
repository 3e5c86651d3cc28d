//! `learner-proc serve`: the learner inside a run. Publishes its current policy, then for
//! every rollout chunk on `rollout`: one PPO update, the new policy on `policy/general`, a
//! metrics row, and a checkpoint every `ppo.checkpoint-every` updates. Resumes from the run's
//! newest good checkpoint when there is one, continuing the policy-version sequence.

use crate::{EpisodeOutcome, Learner, LearnerError, MetricsLog, Rollout};
use common::ipc::{self, Bus, Sender};
use common::wire::{PolicyHeader, RolloutHeader};
use common::{ACT_DIM, Config, OBS_DIM, PolicyLayout, Transition};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Arguments of `serve` (the launcher passes them).
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub join: common::cli::JoinArgs,
    /// The run directory: metrics.csv and checkpoints/ go here.
    #[arg(long)]
    pub out: PathBuf,
    /// Start from this checkpoint instead of the run's newest.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
}

/// Per-env running episode sums, so episode outcomes can be reported from transitions alone.
#[derive(Debug, Default)]
struct EpisodeTracker {
    returns: Vec<f32>,
    steps: Vec<u32>,
}

impl EpisodeTracker {
    /// Adds a chunk's transitions; returns the episodes that ended in it.
    fn feed(&mut self, transitions: &[Transition]) -> Vec<EpisodeOutcome> {
        let mut ended = Vec::new();
        for t in transitions {
            let e = t.env as usize;
            if e >= self.returns.len() {
                self.returns.resize(e + 1, 0.0);
                self.steps.resize(e + 1, 0);
            }
            self.returns[e] += t.reward;
            self.steps[e] += 1;
            if t.terminated != 0 || t.truncated != 0 {
                ended.push(EpisodeOutcome {
                    env: t.env,
                    episode_return: self.returns[e],
                    steps: self.steps[e],
                    success: t.success != 0,
                });
                self.returns[e] = 0.0;
                self.steps[e] = 0;
            }
        }
        ended
    }
}

fn publish(
    tx: &Sender<f32, PolicyHeader>,
    learner: &Learner,
    obs_clip: f64,
) -> Result<(), LearnerError> {
    let c = learner.counters();
    let mut h = PolicyHeader::new(
        learner.layout(),
        learner.policy_version(),
        0,
        obs_clip as f32,
    );
    h.updates = c.update;
    h.env_steps = c.global_step;
    tx.send(h, &learner.policy_weights())?;
    Ok(())
}

/// The learner to start with: a named checkpoint, else the run's newest good one, else new.
fn start(cfg: &Config, args: &ServeArgs, ckpt_dir: &Path) -> Result<Learner, LearnerError> {
    if let Some(path) = &args.checkpoint {
        return Learner::load_checkpoint(cfg, path);
    }
    if crate::checkpoint::list(ckpt_dir)
        .map(|l| !l.is_empty())
        .unwrap_or(false)
    {
        let (learner, path) = Learner::resume(cfg, ckpt_dir)?;
        tracing::info!(checkpoint = %path.display(), version = learner.policy_version(), "resumed");
        return Ok(learner);
    }
    let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
    Learner::new(cfg, layout, cfg.run.seed)
}

pub fn serve(args: &ServeArgs) -> Result<(), LearnerError> {
    let cfg = Config::load(&args.join.config)?;
    let ckpt_dir = args.out.join("checkpoints");
    std::fs::create_dir_all(&ckpt_dir).map_err(LearnerError::io("create", &ckpt_dir))?;
    let mut learner = start(&cfg, args, &ckpt_dir)?;
    let mut log = MetricsLog::open(&args.out)?;
    let bus = Bus::connect(&args.join.run_id, "learner")?;
    let control = bus.control_listener()?;
    let rollout_rx = bus.receiver::<Transition, RolloutHeader>(&ipc::ROLLOUT, None)?;
    let policy_tx =
        bus.sender::<f32, PolicyHeader>(&ipc::POLICY, Some("general"), learner.layout().len())?;
    publish(&policy_tx, &learner, cfg.ppo.obs_clip)?;
    tracing::info!(
        version = learner.policy_version(),
        params = learner.layout().len(),
        "policy published"
    );

    let mut tracker = EpisodeTracker::default();
    let (mut next_chunk, mut missed) = (None::<u64>, 0u64);
    let mut done = false;
    while !done && !bus.stop_requested(&control) {
        policy_tx.update_connections()?;
        rollout_rx.wait(Duration::from_millis(100))?;
        while let Some(sample) = rollout_rx.try_recv()? {
            let h = *sample.user_header();
            let (t, n) = (h.steps as usize, h.envs as usize);
            let data = sample.payload();
            if data.len() != t * n + n || n == 0 {
                tracing::error!(
                    chunk = h.chunk,
                    len = data.len(),
                    steps = t,
                    envs = n,
                    "rollout of the wrong layout refused"
                );
                continue;
            }
            if let Some(want) = next_chunk
                && h.chunk > want
            {
                missed += h.chunk - want;
                tracing::warn!(missed, "rollout chunks missed");
            }
            next_chunk = Some(h.chunk + 1);
            let (transitions, boot) = data.split_at(t * n);
            let bootstrap_obs: Vec<[f32; OBS_DIM]> = boot.iter().map(|b| b.obs).collect();
            let episodes = tracker.feed(transitions);
            let m = learner.update(&Rollout {
                transitions,
                bootstrap_obs: &bootstrap_obs,
                episodes: &episodes,
            })?;
            log.append(&m)?;
            publish(&policy_tx, &learner, cfg.ppo.obs_clip)?;
            let c = learner.counters();
            if learner.checkpoint_due() {
                learner.save_checkpoint(&ckpt_dir)?;
            }
            tracing::info!(
                update = c.update,
                version = m.policy_version,
                env_steps = h.env_steps,
                success = m.success_rate.map_or(-1.0, |s| s),
                ret = m.mean_episode_return.map_or(0.0, |r| r),
                kl = m.approx_kl,
                sps = m.samples_per_second as u64,
                "update"
            );
            if h.env_steps >= cfg.run.total_steps {
                done = true;
            }
        }
    }
    learner.save_checkpoint(&ckpt_dir)?;
    tracing::info!(updates = learner.counters().update, missed, "learner done");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episodes_are_summed_across_chunks() {
        let tr = |env, reward, end: u8, success| Transition {
            env,
            reward,
            terminated: end,
            success,
            ..Transition::default()
        };
        let mut t = EpisodeTracker::default();
        assert!(t.feed(&[tr(0, 1.0, 0, 0), tr(1, 2.0, 0, 0)]).is_empty());
        let ended = t.feed(&[tr(0, 3.0, 1, 1), tr(1, 0.5, 0, 0)]);
        assert_eq!(
            ended,
            vec![EpisodeOutcome {
                env: 0,
                episode_return: 4.0,
                steps: 2,
                success: true
            }]
        );
        let ended = t.feed(&[
            tr(0, 1.0, 0, 0),
            Transition {
                env: 1,
                reward: 1.0,
                truncated: 1,
                ..Transition::default()
            },
        ]);
        assert_eq!(
            ended,
            vec![EpisodeOutcome {
                env: 1,
                episode_return: 3.5,
                steps: 3,
                success: false
            }]
        );
    }
}
