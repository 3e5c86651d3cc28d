//! One measurement: the processes of one stage at one env and thread count, started the way
//! `lavatube run` starts them (same binaries, same arguments, a resolved config file), run
//! to the end of their steps, stopped by the runtime's ladder, and read back: the sim's rate,
//! the reader's tallies and latencies, the learner's metrics, every process's rusage.

use super::config::{Measurement, Plan, Stage};
use super::files::{read_json, write_config};
use super::reader::ReaderResult;
use crate::runtime::{Binaries, Child, Output, Role, Usage, ladder};
use anyhow::{Context, bail};
use common::config::{LearnMode, PolicySlot};
use common::ipc::{self, Bus};
use common::wire::PolicyHeader;
use common::{ACT_DIM, OBS_DIM, Policy, PolicyLayout, Rng, run_dir};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often the launcher looks at its children: rarely enough to cost them nothing.
const POLL: Duration = Duration::from_millis(20);
/// How long the reader may take to subscribe.
const READY_TIMEOUT: Duration = Duration::from_secs(30);

/// A policy in `common::policy`'s layout with random weights: what stage b evaluates and
/// stage c publishes (from stage d on the learner publishes its own). Observation mean 0 and
/// variance 1; LeCun-normal layers, so tanh activations and actions stay of order one and
/// the robots drive about as a policy early in training does.
pub struct RandomPolicy {
    pub layout: PolicyLayout,
    pub weights: Vec<f32>,
    pub obs_clip: f32,
    /// The same policy as a `.policy` file, for `sim-proc --controller policy`.
    pub path: PathBuf,
}

impl RandomPolicy {
    pub fn write(cfg: &common::Config, dir: &Path) -> anyhow::Result<Self> {
        let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
        let mut w = vec![0.0f32; layout.len()];
        w[layout.obs_var()..layout.obs_var() + OBS_DIM].fill(1.0);
        let mut rng = Rng::derive(cfg.run.seed, 0xBE4C);
        for d in layout.dense_layers() {
            let scale = (1.0 / d.inputs as f64).sqrt();
            for x in &mut w[d.weight..d.weight + d.inputs * d.outputs] {
                *x = (rng.normal() * scale) as f32;
            }
        }
        let log_std = layout.log_std();
        w[log_std..].fill(cfg.ppo.init_log_std as f32);
        let obs_clip = cfg.ppo.obs_clip as f32;
        let policy = Policy::new(layout.clone(), w.clone(), obs_clip)?;
        let path = dir.join("random.policy");
        std::fs::write(&path, policy.to_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Self {
            layout,
            weights: w,
            obs_clip,
            path,
        })
    }
}

/// Ctrl-C or SIGTERM during a bench: stop, clean up, exit 130.
#[derive(Debug, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;

/// What a measurement needs from the bench.
pub struct Ctx<'a> {
    pub plan: &'a Plan,
    pub bins: &'a Binaries,
    /// The bench directory; each measurement gets a subdirectory.
    pub dir: &'a Path,
    pub bench_id: &'a str,
    /// The bench's own node, whose signal handling tells a Ctrl-C.
    pub home: &'a Bus,
    pub policy: &'a RandomPolicy,
}

impl Ctx<'_> {
    fn check_interrupt(&self) -> anyhow::Result<()> {
        if self.home.node().wait(Duration::ZERO).is_err() {
            return Err(Interrupted.into());
        }
        Ok(())
    }
}

/// One row of the results: a stage at one env and thread count. `None` where a number does
/// not apply to the stage (no learner, no transport).
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub stage: char,
    pub stage_name: &'static str,
    pub envs: usize,
    pub threads: usize,
    /// The round of the cell it was measured in (`bench.repeats`), from 0.
    pub repeat: usize,
    /// Threads actually stepping: the sim never uses more threads than envs.
    pub effective_threads: usize,
    pub mode: Option<LearnMode>,
    /// Ticks (decision steps per env) the sim ran, and env steps (× envs).
    pub ticks: u64,
    pub env_steps: u64,
    /// The whole measurement, start of the first process to exit of the last.
    pub wall_s: f64,
    /// Decision steps summed over envs per second while stepping (standalone: the sim's
    /// stepping loop; in a run: whole rollout-chunk cycles by the ticks' send timestamps).
    pub decision_steps_per_s: f64,
    /// Decision steps/s × `sim.substeps`.
    pub physics_steps_per_s: f64,
    /// Episodes that ended (the sim's count alone, the reader's in a run). Stages b and c
    /// step the same trajectories, so equal counts show they did the same work.
    pub episodes: u64,
    /// Mean of the learner's `samples_per_second` (minibatch samples × epochs per second of
    /// update) over its updates.
    pub learner_samples_per_s: Option<f64>,
    pub learner_updates: Option<u64>,
    /// Mean of the learner's `mean_policy_lag` (versions behind) over its updates.
    pub policy_lag_versions: Option<f64>,
    /// Per telemetry tick: the reader's clock on taking it minus the sim's send timestamp.
    pub transport_latency_p50_us: Option<f64>,
    pub transport_latency_p99_us: Option<f64>,
    pub telemetry_ticks_received: Option<u64>,
    pub telemetry_ticks_missed: Option<u64>,
    pub rollout_chunks_received: Option<u64>,
    pub rollout_chunks_missed: Option<u64>,
    pub processes: BTreeMap<&'static str, Usage>,
}

/// The part of `sim-proc --json` the bench reads.
#[derive(Debug, Deserialize)]
struct SimResult {
    ticks: u64,
    episodes: u64,
    decision_steps_per_s: f64,
}

/// Updates, mean samples/s and mean policy lag from a learner's `metrics.csv` (numbers and
/// empty fields only, so splitting on commas is exact).
fn learner_metrics(path: &Path) -> anyhow::Result<(u64, f64, f64)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{} is empty", path.display()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .with_context(|| format!("{} has no `{name}` column", path.display()))
    };
    let (sps, lag) = (col("samples_per_second")?, col("mean_policy_lag")?);
    let (mut n, mut sps_sum, mut lag_sum) = (0u64, 0.0, 0.0);
    for line in lines.filter(|l| !l.is_empty()) {
        let fields: Vec<&str> = line.split(',').collect();
        let num = |i: usize| -> anyhow::Result<f64> {
            fields
                .get(i)
                .and_then(|f| f.parse().ok())
                .with_context(|| format!("{}: bad row `{line}`", path.display()))
        };
        sps_sum += num(sps)?;
        lag_sum += num(lag)?;
        n += 1;
    }
    if n == 0 {
        bail!("{}: the learner made no update", path.display());
    }
    Ok((n, sps_sum / n as f64, lag_sum / n as f64))
}

/// Polls `procs` until those at `wait_for` have exited; fails on any unsuccessful exit, on
/// Ctrl-C and at `deadline`. `idle` runs between polls.
fn watch(
    ctx: &Ctx,
    procs: &mut [Child],
    wait_for: &[&str],
    deadline: Instant,
    idle: &mut dyn FnMut() -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    loop {
        let mut done = true;
        for p in procs.iter_mut() {
            let exited = p.poll()?.is_some();
            if let Some(f) = p.failure() {
                bail!("{f}");
            }
            done &= exited || !wait_for.contains(&p.name);
        }
        if done {
            return Ok(());
        }
        ctx.check_interrupt()?;
        if Instant::now() >= deadline {
            bail!(
                "timed out after bench.timeout-s waiting for {}",
                wait_for.join(", ")
            );
        }
        idle()?;
        std::thread::sleep(POLL);
    }
}

/// Starts one process of a measurement, its output straight into its log.
fn spawn(ctx: &Ctx, role: Role, args: &[String], dir: &Path) -> anyhow::Result<Child> {
    Child::spawn(role.name(), ctx.bins.of(role), args, dir, Output::File)
}

/// Runs one measurement in `<bench dir>/<label>/`.
pub fn measure(ctx: &Ctx, m: &Measurement) -> anyhow::Result<Row> {
    let dir = ctx.dir.join(m.label());
    let cfg = ctx.plan.config_for(m, &dir);
    let cfg_path = write_config(&dir, &cfg)?;
    let started = Instant::now();
    let at = Measuring {
        ctx,
        m,
        dir: &dir,
        cfg_path: &cfg_path,
        deadline: started + Duration::from_secs(ctx.plan.bench.timeout_s),
    };
    let mut row = Row::before(ctx.plan, m);
    let procs = if m.stage.joined() {
        let run_id = format!("{}-{}", ctx.bench_id, m.label());
        let joined = in_run(&at, &run_id, &mut row);
        // The processes are gone (reaped or killed when `joined` dropped them), and with them
        // every node of the run: its files can go, whatever happened.
        if let Err(e) = ipc::remove_run(&run_id) {
            eprintln!("lavatube: {e}");
        }
        joined?
    } else {
        standalone(&at, &mut row)?
    };
    row.wall_s = started.elapsed().as_secs_f64();
    row.physics_steps_per_s = row.decision_steps_per_s * cfg.sim.substeps as f64;
    for p in &procs {
        if let Some(usage) = p.usage() {
            row.processes.insert(p.name, usage);
        }
    }
    Ok(row)
}

/// One measurement under way: what it measures, its directory and resolved config file, and
/// when it times out.
struct Measuring<'a> {
    ctx: &'a Ctx<'a>,
    m: &'a Measurement,
    dir: &'a Path,
    cfg_path: &'a Path,
    deadline: Instant,
}

impl Row {
    /// Measurement `m`'s row before anything is measured: what it runs, nothing it measured.
    fn before(plan: &Plan, m: &Measurement) -> Self {
        let ticks = plan.ticks(m.envs);
        Self::unmeasured(
            m.stage,
            m.envs,
            m.threads,
            m.repeat,
            plan.mode(m.stage),
            ticks,
        )
    }

    /// The row of `stage`'s `repeat`-th run at `envs` and `threads`, in `mode`, for `ticks`
    /// ticks, with nothing measured yet.
    pub(super) fn unmeasured(
        stage: Stage,
        envs: usize,
        threads: usize,
        repeat: usize,
        mode: Option<LearnMode>,
        ticks: u64,
    ) -> Self {
        Self {
            stage: stage.letter(),
            stage_name: stage.name(),
            envs,
            threads,
            repeat,
            effective_threads: threads.min(envs),
            mode,
            ticks,
            env_steps: ticks * envs as u64,
            wall_s: 0.0,
            decision_steps_per_s: 0.0,
            physics_steps_per_s: 0.0,
            episodes: 0,
            learner_samples_per_s: None,
            learner_updates: None,
            policy_lag_versions: None,
            transport_latency_p50_us: None,
            transport_latency_p99_us: None,
            telemetry_ticks_received: None,
            telemetry_ticks_missed: None,
            rollout_chunks_received: None,
            rollout_chunks_missed: None,
            processes: BTreeMap::new(),
        }
    }
}

/// Stages a and b: `sim-proc` alone.
fn standalone(at: &Measuring, row: &mut Row) -> anyhow::Result<Vec<Child>> {
    let json = at.dir.join("sim.json");
    let mut args: Vec<String> = vec![
        "--config".into(),
        at.cfg_path.display().to_string(),
        "--steps".into(),
        row.ticks.to_string(),
        "--json".into(),
        json.display().to_string(),
        "--controller".into(),
    ];
    if at.m.stage == Stage::Physics {
        args.push("random".into());
    } else {
        // Sampled like the sim in a run, from the same seed: stages b and c step the very
        // same trajectories, so they differ only by publishing.
        args.extend([
            "policy".into(),
            "--sample".into(),
            "--weights".into(),
            at.ctx.policy.path.display().to_string(),
        ]);
    }
    let mut procs = vec![spawn(at.ctx, Role::Sim, &args, at.dir)?];
    watch(at.ctx, &mut procs, &["sim"], at.deadline, &mut || Ok(()))?;
    let r: SimResult = read_json(&json)?;
    if r.ticks != row.ticks {
        bail!("sim ran {} ticks, {} asked", r.ticks, row.ticks);
    }
    row.decision_steps_per_s = r.decision_steps_per_s;
    row.episodes = r.episodes;
    Ok(procs)
}

/// Where the reader of a run writes its tallies when it ends.
const READER_JSON: &str = "reader.json";

/// Stages c–f: the sim inside a run, with a reader and, from d on, learner and estimator.
fn in_run(at: &Measuring, run_id: &str, row: &mut Row) -> anyhow::Result<Vec<Child>> {
    let bus = Bus::connect(run_id, "bench")?;
    let control = bus.control_notifier()?;
    // Stage c has no learner: the bench publishes the policy a learner would have.
    let policy_tx = if at.m.stage.has_learner() {
        None
    } else {
        let p = at.ctx.policy;
        let tx = bus.sender::<f32, PolicyHeader>(&ipc::POLICY, Some("general"), p.weights.len())?;
        tx.send(PolicyHeader::new(&p.layout, 0, 0, p.obs_clip), &p.weights)?;
        Some(tx)
    };
    let mut procs = vec![start_reader(at, run_id)?];
    start_run(at, run_id, &mut procs)?;

    watch(at.ctx, &mut procs, &["sim"], at.deadline, &mut || {
        // A late subscriber gets the policy's history only when its publisher acts.
        if let Some(tx) = &policy_tx {
            tx.update_connections()?;
        }
        Ok(())
    })?;
    // The learner stops by itself once it has learned from the last chunk.
    watch(
        at.ctx,
        &mut procs,
        &["learner"],
        at.deadline,
        &mut || Ok(()),
    )?;
    let grace = Duration::from_millis(at.ctx.plan.runtime.supervise.grace_ms);
    let mut children: Vec<&mut Child> = procs.iter_mut().collect();
    ladder::stop(
        &mut children,
        &|| {
            if let Err(e) = ipc::request_shutdown(&control) {
                eprintln!("lavatube: {e}");
            }
        },
        grace,
    );
    if let Some(f) = procs.iter().find_map(Child::failure) {
        bail!("{f}");
    }
    read_run(at, &procs[0], row)?;
    drop((policy_tx, control, bus));
    Ok(procs)
}

/// The arguments of a process joining run `run_id`: its subcommand, if any, then the config.
fn join_args(cmd: Option<&str>, cfg_path: &Path, run_id: &str) -> Vec<String> {
    let mut a: Vec<String> = cmd.map(String::from).into_iter().collect();
    a.extend([
        "--config".into(),
        cfg_path.display().to_string(),
        "--run-id".into(),
        run_id.into(),
    ]);
    a
}

/// Starts the reader of run `run_id` and waits until it has subscribed: telemetry has no
/// history, so the sim starts only once the reader cannot miss a tick.
fn start_reader(at: &Measuring, run_id: &str) -> anyhow::Result<Child> {
    let (ready, out) = (at.dir.join("reader.ready"), at.dir.join(READER_JSON));
    let reader_args = vec![
        "bench-reader".into(),
        "--run-id".into(),
        run_id.into(),
        "--out".into(),
        out.display().to_string(),
        "--ready".into(),
        ready.display().to_string(),
    ];
    let mut reader = spawn(at.ctx, Role::Reader, &reader_args, at.dir)?;
    let ready_by = (Instant::now() + READY_TIMEOUT).min(at.deadline);
    while !ready.exists() {
        if reader.poll()?.is_some() {
            bail!(
                "the reader exited before subscribing; log: {}",
                reader.log().display()
            );
        }
        at.ctx.check_interrupt()?;
        if Instant::now() >= ready_by {
            bail!(
                "the reader did not subscribe in time; log: {}",
                reader.log().display()
            );
        }
        std::thread::sleep(POLL);
    }
    Ok(reader)
}

/// Starts the rest of run `run_id` after its reader: the estimator (stage f), the learner
/// (from stage d on), and the sim last.
fn start_run(at: &Measuring, run_id: &str, procs: &mut Vec<Child>) -> anyhow::Result<()> {
    let (ctx, dir) = (at.ctx, at.dir);
    let join = |cmd: Option<&str>| join_args(cmd, at.cfg_path, run_id);
    if at.m.stage == Stage::Estimator {
        procs.push(spawn(ctx, Role::Estimator, &join(Some("serve")), dir)?);
    }
    if at.m.stage.has_learner() {
        let mut a = join(Some("serve"));
        a.extend(["--out".into(), dir.display().to_string()]);
        procs.push(spawn(ctx, Role::Learner(PolicySlot::General), &a, dir)?);
    }
    procs.push(spawn(ctx, Role::Sim, &join(None), dir)?);
    Ok(())
}

/// Fills `row` from what a finished run left: the reader's tallies and latencies, and from
/// stage d on the learner's metrics.
fn read_run(at: &Measuring, reader: &Child, row: &mut Row) -> anyhow::Result<()> {
    let r: ReaderResult = read_json(&at.dir.join(READER_JSON))?;
    let expected_chunks = at.ctx.plan.chunks(at.m.envs);
    row.decision_steps_per_s = r.decision_steps_per_s.with_context(|| {
        format!(
            "the reader saw too few ticks; log: {}",
            reader.log().display()
        )
    })?;
    row.episodes = r.episode_ends;
    row.transport_latency_p50_us = r.latency_p50_us;
    row.transport_latency_p99_us = r.latency_p99_us;
    row.telemetry_ticks_received = Some(r.ticks);
    row.telemetry_ticks_missed = Some(row.ticks.saturating_sub(r.ticks));
    row.rollout_chunks_received = Some(r.chunks);
    row.rollout_chunks_missed = Some(expected_chunks.saturating_sub(r.chunks));
    if at.m.stage.has_learner() {
        let (updates, sps, lag) = learner_metrics(&at.dir.join(run_dir::METRICS_CSV))?;
        row.learner_updates = Some(updates);
        row.learner_samples_per_s = Some(sps);
        row.policy_lag_versions = Some(lag);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::policy::Scratch;

    #[test]
    fn learner_metrics_average_the_updates() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("metrics.csv");
        std::fs::write(
            &path,
            "update,samples_per_second,mean_policy_lag,success_rate\n1,100,0,\n2,300,1.5,0.5\n",
        )
        .expect("write");
        assert_eq!(learner_metrics(&path).expect("metrics"), (2, 200.0, 0.75));
        std::fs::write(&path, "update,samples_per_second,mean_policy_lag\n").expect("write");
        assert!(learner_metrics(&path).is_err(), "no update is an error");
    }

    #[test]
    fn the_random_policy_round_trips_as_a_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let cfg = common::Config::default();
        let p = RandomPolicy::write(&cfg, dir.path()).expect("write");
        let bytes = std::fs::read(&p.path).expect("read");
        let back = Policy::from_bytes(&bytes, &p.path).expect("parse");
        assert_eq!(back.weights(), &p.weights[..]);
        let mut mean = [0.0; ACT_DIM];
        back.mean_action(&[0.3; OBS_DIM], &mut mean, &mut Scratch::default());
        assert!(
            mean.iter().all(|a| a.is_finite() && a.abs() < 10.0),
            "{mean:?}"
        );
        assert!(
            mean.iter().any(|a| a.abs() > 1e-3),
            "actions move the robot: {mean:?}"
        );
    }
}
