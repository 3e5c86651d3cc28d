//! `learner-proc serve`: the learner inside a run. Publishes its current policy, then for
//! every rollout chunk on `rollout`: one PPO update, the new policy on `policy/general`, a
//! metrics row, and a checkpoint every `ppo.checkpoint-every` updates, after which it redraws
//! `<out>/curves.png` (at most twice a minute, and at the end).
//!
//! What it starts from, first match wins: `--checkpoint` (resume that file exactly); the run
//! directory's newest good checkpoint (resume, continuing the policy-version sequence);
//! `--init-from` (a warm start, [`Learner::warm_start`]); a new learner from the config's seed.
//! The run's own checkpoints beat `--init-from` so that a learner restarted with the same
//! command line continues its run instead of warm-starting it again.

use crate::rounds::Round;
use crate::writes::Writes;
use crate::{EpisodeOutcome, Learner, LearnerError, MetricsLog, Rollout, curves};
use common::config::{LearnMode, PolicySlot};
use common::ipc::{self, Bus, Sender};
use common::refusals::Refusals;
use common::wire::{PolicyHeader, RolloutHeader};
use common::{ACT_DIM, Config, OBS_DIM, PolicyLayout, Transition};
use common::{rollout, run_dir};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Arguments of `serve` (the launcher passes them).
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub join: common::cli::JoinArgs,
    /// The run directory: metrics.csv, curves.png and checkpoints/ go here.
    #[arg(long)]
    pub out: PathBuf,
    /// Start from this checkpoint instead of the run's newest.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// Warm start: take the actor, critic and observation statistics of this checkpoint file
    /// but start counters, optimizer, learning-rate schedule and RNG afresh (e.g. the general
    /// model from the flat model), at `run.init-learning-rate` where set. Its network must
    /// match `ppo.hidden`. Ignored for the weights when the run directory already has
    /// checkpoints or `--checkpoint` names one: the learner resumes that, still at
    /// `run.init-learning-rate` (a swapped or restarted warm-started learner keeps its rate).
    #[arg(long)]
    pub init_from: Option<PathBuf>,
    /// Only check that this learner can start (config, checkpoint, network shape), print
    /// what it would start from, and exit without joining the run. `lavatube swap-learner`
    /// runs this before it stops the old learner.
    #[arg(long)]
    pub check: bool,
    /// The policy slot this learner fills: `general` trains on every transition, `flat` and
    /// `rough` only on those the estimator assigned to their terrain (SPEC S8).
    #[arg(long, default_value = "general", value_parser = PolicySlot::parse)]
    pub slot: PolicySlot,
    /// Serve the starting policy without training (`run.frozen`, for evaluation): every
    /// rollout chunk is answered with the same weights; no update, no checkpoint.
    #[arg(long)]
    pub frozen: bool,
    /// Sims that feed this learner (on a learner host, `net.sim-hosts`): it is done once
    /// that many have each sent the chunk that completes their `run.total-steps`.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub sources: u32,
}

/// How many transitions were acted on by a policy 0, 1, 2, 3, 4–7 and 8 or more versions
/// older than the learner's (DESIGN §3: policy lag), over the learner's life.
#[derive(Debug, Default)]
struct LagHistogram([u64; 6]);

impl LagHistogram {
    const LABELS: [&'static str; 6] = ["0", "1", "2", "3", "4-7", "8+"];

    fn add(&mut self, learner_version: u32, transitions: &[Transition]) {
        for t in transitions {
            let lag = learner_version.saturating_sub(t.policy_version);
            let bin = match lag {
                0..=3 => lag as usize,
                4..=7 => 4,
                _ => 5,
            };
            self.0[bin] += 1;
        }
    }

    /// `0: 97.0%, 1: 3.0%, …` (bins with no transitions left out).
    fn summary(&self) -> String {
        let total = self.0.iter().sum::<u64>().max(1) as f64;
        Self::LABELS
            .iter()
            .zip(self.0)
            .filter(|(_, n)| *n > 0)
            .map(|(l, n)| format!("{l}: {:.1}%", 100.0 * n as f64 / total))
            .collect::<Vec<_>>()
            .join(", ")
    }
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

/// What the learner has received from one source (one sim; DESIGN §9): its chunk sequence,
/// the chunks missed in it, its step count and its episodes in progress.
#[derive(Debug, Default)]
struct Source {
    next_chunk: Option<u64>,
    chunks: u64,
    missed: u64,
    env_steps: u64,
    episodes: EpisodeTracker,
}

impl Source {
    /// Takes chunk `h`: counts it, and any chunks missed before it.
    fn receive(&mut self, h: &RolloutHeader) {
        if let Some(want) = self.next_chunk
            && h.chunk > want
        {
            self.missed += h.chunk - want;
            tracing::warn!(
                source = h.source,
                missed = self.missed,
                "rollout chunks missed"
            );
        }
        self.next_chunk = Some(h.chunk + 1);
        self.chunks += 1;
        self.env_steps = h.env_steps;
    }
}

/// `source 0: 12 chunks (0 missed), source 1: …`, for the closing log line.
fn sources_summary(sources: &BTreeMap<u32, Source>) -> String {
    sources
        .iter()
        .map(|(id, s)| format!("source {id}: {} chunks ({} missed)", s.chunks, s.missed))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Publishes the learner's policy; `chunks_seen` tells a waiting sync-mode sim which of its
/// rollout chunks this learner has consumed.
fn publish(
    tx: &Sender<f32, PolicyHeader>,
    learner: &Learner,
    slot: PolicySlot,
    obs_clip: f64,
    chunks_seen: u64,
    write_failures: u32,
) -> Result<(), LearnerError> {
    let c = learner.counters();
    let mut h = PolicyHeader::new(
        learner.layout(),
        learner.policy_version(),
        slot.index() as u32,
        obs_clip as f32,
    );
    h.updates = c.update;
    h.env_steps = c.global_step;
    h.chunks_seen = chunks_seen;
    h.write_failures = write_failures;
    tx.send(h, &learner.policy_weights())?;
    Ok(())
}

/// The config a learner trains with: one given `--init-from` (also once it resumes its own
/// checkpoints) at `run.init-learning-rate` where that is set.
fn learner_config(cfg: &Config, args: &ServeArgs) -> Config {
    let mut cfg = cfg.clone();
    if args.init_from.is_some()
        && let Some(lr) = cfg.run.init_learning_rate
    {
        cfg.ppo.learning_rate = lr;
    }
    cfg
}

/// The learner to start with, in the order the module documentation gives, with a line
/// saying which.
fn start(
    cfg: &Config,
    args: &ServeArgs,
    ckpt_dir: &Path,
) -> Result<(Learner, String), LearnerError> {
    let cfg = &learner_config(cfg, args);
    let from = |learner: &Learner, path: &Path| {
        format!(
            "resumes {} at version {} (optimizer digest {:08x})",
            path.display(),
            learner.policy_version(),
            learner.adam.digest()
        )
    };
    if let Some(path) = &args.checkpoint {
        let learner = Learner::load_checkpoint(cfg, path)?;
        let said = from(&learner, path);
        return Ok((learner, said));
    }
    if crate::checkpoint::list(ckpt_dir).is_ok_and(|l| !l.is_empty()) {
        let (learner, path) = Learner::resume(cfg, ckpt_dir)?;
        let mut said = from(&learner, &path);
        if let Some(init) = &args.init_from {
            said += &format!(
                " (not --init-from {}: the run directory has checkpoints)",
                init.display()
            );
        }
        return Ok((learner, said));
    }
    if let Some(path) = &args.init_from {
        let learner = Learner::warm_start(cfg, path)?;
        let said = format!(
            "warm-starts from {}: its weights and observation statistics, fresh counters, \
             optimizer and learning-rate schedule",
            path.display()
        );
        return Ok((learner, said));
    }
    let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
    let learner = Learner::new(cfg, layout, cfg.run.seed)?;
    Ok((learner, "starts a new policy".into()))
}

/// `<out>/curves.png`, redrawn from the metrics after a checkpoint (once the policy went
/// out, so no sim waits for it), at most every [`Self::MIN_INTERVAL`], and at the end. A
/// figure that cannot be drawn is logged, never a reason to stop training.
struct CurvesFigure {
    png: PathBuf,
    drawn: Option<Instant>,
}

impl CurvesFigure {
    /// Reading, drawing and encoding 20k updates took ~0.4 s of one core here (700 updates
    /// ~0.2 s), and checkpoints may come every update (`ppo.checkpoint-every` defaults to 1):
    /// redrawing at each would take a real share of the two cores from the sim and the update.
    const MIN_INTERVAL: Duration = Duration::from_secs(30);

    fn new(out: &Path) -> Self {
        Self {
            png: out.join(run_dir::CURVES_PNG),
            drawn: None,
        }
    }

    /// Redraws unless the last drawing is younger than the interval and `force` is false.
    fn redraw(&mut self, metrics: &Path, force: bool) {
        if !force && self.drawn.is_some_and(|t| t.elapsed() < Self::MIN_INTERVAL) {
            return;
        }
        // A learner stopped before its first update has nothing to draw.
        if std::fs::metadata(metrics).is_ok_and(|m| m.len() == 0) {
            return;
        }
        if let Err(e) = curves::plot(metrics, &self.png) {
            tracing::warn!(error = %e, "learning curves not redrawn");
        }
        self.drawn = Some(Instant::now());
    }
}

/// Where the learner writes besides its policies: checkpoints, the metrics CSV and the
/// learning-curves figure.
struct RunFiles {
    ckpt_dir: PathBuf,
    log: MetricsLog,
    figure: CurvesFigure,
}

impl RunFiles {
    /// Opens the metrics CSV in `out`; checkpoints go to `ckpt_dir`.
    fn open(out: &Path, ckpt_dir: PathBuf) -> Result<Self, LearnerError> {
        Ok(Self {
            ckpt_dir,
            log: MetricsLog::open(out)?,
            figure: CurvesFigure::new(out),
        })
    }
}

/// Runs the learner in the run `args` names until each of its sims has sent its last chunk
/// or the run asks it to stop.
pub fn serve(args: &ServeArgs) -> Result<(), LearnerError> {
    let cfg = Config::load(&args.join.config)?;
    let ckpt_dir = args.out.join(run_dir::CHECKPOINTS);
    std::fs::create_dir_all(&ckpt_dir).map_err(LearnerError::io("create", &ckpt_dir))?;
    let (mut learner, from) = start(&cfg, args, &ckpt_dir)?;
    if args.check {
        #[allow(clippy::print_stdout)] // `--check` reports on stdout, for the launcher
        {
            println!("{from}");
        }
        return Ok(());
    }
    tracing::info!(
        engine = ?cfg.ppo.engine,
        threads = learner.update_threads(),
        "learner {from}"
    );
    let files = RunFiles::open(&args.out, ckpt_dir)?;
    learner.play(args.slot);
    let bus = Bus::connect(&args.join.run_id, args.slot.learner_name())?;
    let control = bus.control_listener()?;
    let rollout_rx = bus.receiver::<Transition, RolloutHeader>(&ipc::ROLLOUT, None)?;
    let mut trainer = Trainer::publish_first(&bus, args, &cfg, learner, files)?;
    while !trainer.done && !bus.stop_requested(&control) {
        trainer.policy_tx.update_connections()?;
        rollout_rx.wait(Duration::from_millis(100))?;
        while let Some(sample) = rollout_rx.try_recv()? {
            trainer.take(*sample.user_header(), sample.payload())?;
        }
    }
    trainer.finish();
    Ok(())
}

/// The learner at work: its policy service, its files and what it has counted of the
/// rollout chunks so far.
struct Trainer<'a> {
    args: &'a ServeArgs,
    cfg: &'a Config,
    learner: Learner,
    files: RunFiles,
    policy_tx: Sender<f32, PolicyHeader>,
    sources: BTreeMap<u32, Source>,
    /// Sync mode across several sims: the round of their chunks in progress.
    rounds: Option<Round>,
    lags: LagHistogram,
    writes: Writes,
    refused: Refusals,
    /// Every sim has sent the chunk that completes its `run.total-steps`.
    done: bool,
}

impl<'a> Trainer<'a> {
    /// Opens the policy service of `args.slot` on `bus` and publishes the starting policy.
    fn publish_first(
        bus: &Bus,
        args: &'a ServeArgs,
        cfg: &'a Config,
        learner: Learner,
        files: RunFiles,
    ) -> Result<Self, LearnerError> {
        let policy_tx = bus.sender::<f32, PolicyHeader>(
            &ipc::POLICY,
            Some(args.slot.name()),
            learner.layout().len(),
        )?;
        publish(&policy_tx, &learner, args.slot, cfg.ppo.obs_clip, 0, 0)?;
        tracing::info!(
            version = learner.policy_version(),
            params = learner.layout().len(),
            "policy published"
        );
        Ok(Self {
            args,
            cfg,
            learner,
            files,
            policy_tx,
            sources: BTreeMap::new(),
            rounds: (cfg.run.mode == LearnMode::Sync && args.sources > 1).then(Round::default),
            lags: LagHistogram::default(),
            writes: Writes::default(),
            refused: Refusals::new("rollout chunk"),
            done: false,
        })
    }

    /// Publishes the current policy. Every consumed chunk is answered with a policy, so a
    /// sync-mode sim never waits in vain.
    fn answer(&self, chunks_seen: u64) -> Result<(), LearnerError> {
        publish(
            &self.policy_tx,
            &self.learner,
            self.args.slot,
            self.cfg.ppo.obs_clip,
            chunks_seen,
            self.writes.failures(),
        )
    }

    /// Takes one rollout chunk (`h`, `data`): drops a bad one, counts it, and trains on it
    /// (or on the round it completes) unless the learner is frozen.
    fn take(&mut self, h: RolloutHeader, data: &[Transition]) -> Result<(), LearnerError> {
        let (t, n) = (h.steps as usize, h.envs as usize);
        // DESIGN §2: a bad chunk is dropped and counted; it never reaches PPO, and it is
        // not answered (its chunk id may be anything).
        if let Some(kind) = rollout::chunk_refusal(&h, data) {
            self.refused.refuse(
                kind,
                &format!("chunk {}: {} × {} + {} of {}", h.chunk, t, n, n, data.len()),
            );
            return Ok(());
        }
        let source = self.sources.entry(h.source).or_default();
        source.receive(&h);
        // Each sim steps `run.total-steps`; the learner is done once each of its sims
        // has sent its last chunk.
        self.done = self.sources.len() >= self.args.sources as usize
            && self
                .sources
                .values()
                .all(|s| s.env_steps >= self.cfg.run.total_steps);
        if self.args.frozen {
            return self.answer(h.chunk + 1);
        }
        let (transitions, boot) = data.split_at(t * n);
        let bootstrap_obs: Vec<[f32; OBS_DIM]> = boot.iter().map(|b| b.obs).collect();
        let episodes = self
            .sources
            .entry(h.source)
            .or_default()
            .episodes
            .feed(transitions);
        self.lags.add(self.learner.policy_version(), transitions);
        // Sync mode across several sims: one update per round of their chunks.
        let merged = match self.rounds.as_mut() {
            None => None,
            Some(round) => {
                round.add(
                    h.source,
                    h.chunk,
                    t,
                    transitions.to_vec(),
                    bootstrap_obs.clone(),
                    episodes.clone(),
                );
                let Some(m) = round.complete(self.args.sources as usize) else {
                    return Ok(());
                };
                Some(m)
            }
        };
        let chunks_seen = merged.as_ref().map_or(h.chunk + 1, |m| m.chunks_seen);
        let rollout = match &merged {
            None => Rollout {
                transitions,
                bootstrap_obs: &bootstrap_obs,
                episodes: &episodes,
            },
            Some(m) => Rollout {
                transitions: &m.transitions,
                bootstrap_obs: &m.bootstrap_obs,
                episodes: &m.episodes,
            },
        };
        self.train(&h, &rollout, chunks_seen)
    }

    /// One PPO update on `rollout`, then its metrics row, a checkpoint when due, the new
    /// policy (answering `chunks_seen` chunks) and a log line.
    fn train(
        &mut self,
        h: &RolloutHeader,
        rollout: &Rollout,
        chunks_seen: u64,
    ) -> Result<(), LearnerError> {
        let mut m = match self.learner.update(rollout) {
            Ok(m) => m,
            // One bad chunk (all stale, non-finite loss) is skipped, not fatal; the
            // policy is published anyway so a waiting sync-mode sim goes on.
            Err(e @ (LearnerError::Rollout { .. } | LearnerError::NonFinite { .. })) => {
                tracing::warn!(chunk = h.chunk, error = %e, "chunk not trained on");
                return self.answer(chunks_seen);
            }
            Err(e) => return Err(e),
        };
        m.chunks_by_source = self
            .sources
            .iter()
            .map(|(id, s)| format!("{id}:{}", s.chunks))
            .collect::<Vec<_>>()
            .join(" ");
        self.writes.attempt("metrics", self.files.log.append(&m));
        // Checkpoint before publishing: every published version can be resumed, so a
        // learner restarted after kill -9 continues the version sequence.
        if self.learner.checkpoint_due() {
            let saved = self.learner.save_checkpoint(&self.files.ckpt_dir);
            self.writes.attempt("checkpoint", saved);
        }
        self.answer(chunks_seen)?;
        if self.learner.checkpoint_due() {
            self.files.figure.redraw(self.files.log.path(), false);
        }
        let c = self.learner.counters();
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
        Ok(())
    }

    /// The last checkpoint (unless frozen), the final learning curves and the closing log
    /// line.
    fn finish(mut self) {
        if !self.args.frozen {
            let saved = self.learner.save_checkpoint(&self.files.ckpt_dir);
            self.writes.attempt("checkpoint", saved);
        }
        self.files.figure.redraw(self.files.log.path(), true);
        tracing::info!(
            updates = self.learner.counters().update,
            version = self.learner.policy_version(),
            chunks_missed = self.sources.values().map(|s| s.missed).sum::<u64>(),
            sources = %sources_summary(&self.sources),
            write_failures = self.writes.failures(),
            refused = %self.refused.summary(),
            "learner done; policy lag of the transitions received (versions: share): {}",
            self.lags.summary()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checkpoint::Checkpoint;
    use crate::cli::{Cli, Command};
    use crate::ppo::tests::{OwnedRollout, learner, small_config};
    use clap::Parser;

    /// `serve` arguments as the command line gives them.
    fn serve_args(extra: &[&str]) -> Result<ServeArgs, clap::Error> {
        let argv = [
            "learner-proc",
            "serve",
            "--config",
            "c.toml",
            "--run-id",
            "t",
            "--out",
            "o",
        ];
        let cli = Cli::try_parse_from(argv.iter().chain(extra))?;
        let Command::Serve(args) = cli.command else {
            panic!("parsed as another command: {:?}", cli.command)
        };
        Ok(args)
    }

    /// The first checkpoint draws, the next ones within the interval do not, the last does.
    #[test]
    fn curves_are_redrawn_at_most_every_interval_and_at_the_end() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(run_dir::METRICS_CSV);
        std::fs::write(&metrics, "global_step,mean_episode_return,success_rate,policy_loss,value_loss,entropy,approx_kl,clip_fraction,explained_variance\n")
            .expect("write");
        let mut figure = CurvesFigure::new(dir.path());
        figure.redraw(&metrics, false);
        assert!(figure.png.exists(), "first checkpoint");
        std::fs::remove_file(&figure.png).expect("rm");
        figure.redraw(&metrics, false);
        assert!(!figure.png.exists(), "too soon");
        figure.redraw(&metrics, true);
        assert!(figure.png.exists(), "the end");
    }

    /// `--init-from` warm-starts a run directory without checkpoints; once the run has its
    /// own, a learner restarted with the same arguments resumes them instead.
    #[test]
    fn the_runs_own_checkpoints_beat_init_from() {
        let mut cfg = small_config(128, 10);
        cfg.run.init_learning_rate = Some(1e-4);
        let source_dir = tempfile::tempdir().expect("tempdir");
        let mut source = learner(&cfg, 31);
        let r = OwnedRollout::acted_by(&source, 64, 4, 32);
        source.update(&r.view()).expect("update");
        let source_path = source.save_checkpoint(source_dir.path()).expect("save");
        let run = tempfile::tempdir().expect("tempdir");
        let ckpt_dir = run.path().join(run_dir::CHECKPOINTS);
        let path = source_path.to_str().expect("utf-8 temp path");
        let args = serve_args(&["--init-from", path]).expect("args");

        let (mut warm, said) = start(&cfg, &args, &ckpt_dir).expect("warm start");
        assert!(said.starts_with("warm-starts from"), "{said}");
        assert_eq!(warm.counters(), crate::Counters::default());
        assert_eq!(warm.policy_weights(), source.policy_weights());
        assert_eq!(warm.learning_rate(), 1e-4, "run.init-learning-rate");

        warm.update(&r.view()).expect("update");
        warm.save_checkpoint(&ckpt_dir).expect("save");
        let (resumed, said) = start(&cfg, &args, &ckpt_dir).expect("restart");
        assert!(said.contains("not --init-from"), "{said}");
        assert_eq!(resumed.checkpoint(), warm.checkpoint());
        assert_eq!(resumed.learning_rate(), warm.learning_rate());

        // A swap to a named checkpoint in a warm-started run: the file wins, the rate stays.
        let named = serve_args(&["--init-from", path, "--checkpoint", path]).expect("args");
        let (swapped, said) = start(&cfg, &named, &ckpt_dir).expect("named checkpoint");
        assert!(said.starts_with(&format!("resumes {path}")), "{said}");
        // run.init-learning-rate, annealed over the file's 256 of the run's 2560 steps.
        assert_eq!(source.counters().global_step, 256);
        let rate = 1e-4 * (1.0 - 256.0 / 2560.0);
        assert_eq!(swapped.learning_rate(), rate);
        let file_at_this_runs_rate = Checkpoint {
            learning_rate: rate,
            ..source.checkpoint()
        };
        assert_eq!(swapped.checkpoint(), file_at_this_runs_rate);
    }

    #[test]
    fn lag_histogram_bins_versions_behind() {
        let acted = |v| Transition {
            policy_version: v,
            ..Transition::default()
        };
        let mut h = LagHistogram::default();
        h.add(
            10,
            &[
                acted(10),
                acted(10),
                acted(9),
                acted(5),
                acted(1),
                acted(11),
            ],
        );
        // 11 is from a newer policy than the learner's (a restarted learner): lag 0.
        assert_eq!(h.0, [3, 1, 0, 0, 1, 1]);
        assert_eq!(h.summary(), "0: 50.0%, 1: 16.7%, 4-7: 16.7%, 8+: 16.7%");
    }

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
