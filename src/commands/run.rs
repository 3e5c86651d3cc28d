//! `lavatube run`: one training run. Validates the config before anything starts, creates the
//! run directory, starts learner, estimator and simulator, shows progress from the run's own
//! telemetry, stops everything on Ctrl-C or failure, and prints a summary.

use super::{UserError, swap};
use crate::supervise::{self, Event, Proc, Slot, Spec};
use anyhow::Context;
use common::Config;
use common::config::PolicySlot;
use common::ipc::{self, Bus};
use common::wire::{EnvTick, SwapReply, TerrainEstimate, TerrainHeader, TickHeader};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Config file (TOML). Without one: the built-in defaults, documented in
    /// `common/src/config.rs` (the README's main job is `configs/default.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run id: names the run directory and prefixes every shared-memory resource. Default: a new one.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: Option<String>,
    /// No progress bar (for logs and CI).
    #[arg(long)]
    pub quiet: bool,
}

/// A fresh run id: seconds since the epoch and the launcher's pid, in base 36-ish hex.
fn new_run_id() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!("r{secs:x}-{:x}", std::process::id())
}

/// What the run's telemetry and terrain services said last.
#[derive(Debug, Default, Clone, Copy)]
struct Progress {
    tick: TickHeader,
    terrain: TerrainHeader,
    /// Envs see flat and rough ground (both areas, or the mixed course): only then does
    /// scoring a two-class terrain estimate mean anything.
    both_areas: bool,
}

impl Progress {
    fn success_rate(&self) -> f64 {
        self.tick.successes as f64 / self.tick.episodes.max(1) as f64
    }

    /// Mean and std of the reach time of successful episodes, seconds (SPEC S8, Table 1).
    fn reach_seconds(&self, decision_dt: f64) -> Option<(f64, f64)> {
        let n = self.tick.successes as f64;
        (n > 0.0).then(|| {
            let mean = self.tick.reach_ticks as f64 / n;
            let var = (self.tick.reach_ticks_sq as f64 / n - mean * mean).max(0.0);
            (mean * decision_dt, var.sqrt() * decision_dt)
        })
    }

    fn terrain_accuracy(&self) -> Option<f64> {
        (self.both_areas && self.terrain.scored > 0)
            .then(|| self.terrain.correct as f64 / self.terrain.scored as f64)
    }
}

/// The learner's arguments: `join` (serve, config, run id), its run directory, and a
/// checkpoint to start from instead of the run's newest.
pub fn learner_args(join: &[String], dir: &Path, checkpoint: Option<&Path>) -> Vec<String> {
    let mut a = join.to_vec();
    a.extend(["--out".into(), dir.display().to_string()]);
    if let Some(c) = checkpoint {
        a.extend(["--checkpoint".into(), c.display().to_string()]);
    }
    a
}

/// Where a slot's learner writes metrics and checkpoints: the run directory for `general`,
/// a subdirectory per specialist.
pub fn learner_dir(run_dir: &Path, slot: PolicySlot) -> PathBuf {
    match slot {
        PolicySlot::General => run_dir.to_path_buf(),
        s => run_dir.join(s.learner_name()),
    }
}

/// Stops every slot's process (see [`supervise::stop`]).
fn stop_all(slots: &mut [Slot], request: &dyn Fn(), grace: Duration) {
    let mut procs: Vec<&mut Proc> = slots.iter_mut().map(|s| &mut s.proc).collect();
    supervise::stop(&mut procs, request, grace);
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let cfg = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let run_id = args.run_id.clone().unwrap_or_else(new_run_id);
    Ok(if execute(&cfg, &run_id, &run_id, args.quiet)? {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(130)
    })
}

/// Where a run with `run.telemetry-csv` keeps the sim's telemetry, in its run directory.
pub(crate) const TELEMETRY_CSV: &str = "telemetry.csv";

/// The launcher's node name on a run's bus: a live one means the run id is taken.
pub(crate) const LAUNCHER_NODE: &str = "launcher";

/// Runs `cfg` in `<run.out-dir>/<dir_name>/` to the end, its processes meeting in the shared
/// memory of run `run_id`. Returns false when interrupted (Ctrl-C); fails when a process
/// failed for good, or before anything starts when a live run already uses `run_id`.
pub fn execute(cfg: &Config, dir_name: &str, run_id: &str, quiet: bool) -> anyhow::Result<bool> {
    let bins = [
        supervise::locate("learner-proc")?,
        supervise::locate("estimator-proc")?,
        supervise::locate("sim-proc")?,
    ];
    let run_id = run_id.to_string();
    // Two runs on one id would read each other's messages and remove each other's shared
    // memory at the end. Other nodes (monitors, tests watching the run) may come first.
    let live: Vec<String> = ipc::list_nodes(&run_id)
        .unwrap_or_default()
        .into_iter()
        .filter(|n| n.alive && n.name == LAUNCHER_NODE)
        .map(|n| format!("{} (pid {})", n.name, n.pid))
        .collect();
    if !live.is_empty() {
        return Err(UserError(format!(
            "run id `{run_id}` is in use by a live run ({}): pick another --run-id",
            live.join(", ")
        ))
        .into());
    }
    // Absolute, so logs and the children's arguments name it unambiguously.
    let dir = std::path::absolute(cfg.run.out_dir.join(dir_name))
        .with_context(|| format!("cannot resolve {}", cfg.run.out_dir.display()))?;
    if dir.exists() {
        return Err(UserError(format!(
            "run directory {} already exists: pick another --run-id",
            dir.display()
        ))
        .into());
    }
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).with_context(|| format!("cannot create {}", logs.display()))?;
    let cfg_path = dir.join("config.toml");
    std::fs::write(&cfg_path, cfg.to_toml())
        .with_context(|| format!("cannot write {}", cfg_path.display()))?;

    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(cfg.run.total_steps)
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} steps {per_sec} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    supervise::say(
        &bar,
        format!(
            "run {run_id}: {}, {:?} mode → {}",
            cfg.sim.describe_envs(),
            cfg.run.mode,
            dir.display()
        ),
    );

    let bus = Bus::connect(&run_id, LAUNCHER_NODE)?;
    let control = bus.control_notifier()?;
    let tele_rx = bus.receiver::<EnvTick, TickHeader>(&ipc::TELEMETRY, None)?;
    let terrain_rx = bus.receiver::<TerrainEstimate, TerrainHeader>(&ipc::TERRAIN, None)?;
    let swap_server = bus.swap_server()?;

    let join = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
        v.extend([
            "--config".into(),
            cfg_path.display().to_string(),
            "--run-id".into(),
            run_id.clone(),
        ]);
        v
    };
    let [learner_bin, estimator_bin, sim_bin] = bins;
    let sup = &cfg.supervise;
    let learners = cfg.run.learners.iter().map(|&slot| {
        let mut join = join(&["serve", "--slot", slot.name()]);
        if let Some(init) = &cfg.run.init_from {
            join.extend(["--init-from".into(), init.display().to_string()]);
        }
        Spec {
            name: slot.learner_name(),
            bin: learner_bin.clone(),
            args: learner_args(&join, &learner_dir(&dir, slot), None),
            policy: sup.learner,
        }
    });
    let frozen = cfg.run.frozen.iter().map(|(&slot, ckpt)| Spec {
        name: slot.learner_name(),
        bin: learner_bin.clone(),
        args: learner_args(
            &join(&["serve", "--slot", slot.name(), "--frozen"]),
            &learner_dir(&dir, slot),
            Some(ckpt),
        ),
        policy: sup.learner,
    });
    let mut sim_args = join(&[]);
    if cfg.run.telemetry_csv {
        sim_args.extend([
            "--telemetry".into(),
            dir.join(TELEMETRY_CSV).display().to_string(),
        ]);
    }
    let specs = learners.chain(frozen).chain([
        Spec {
            name: "estimator",
            bin: estimator_bin,
            args: join(&["serve"]),
            policy: sup.estimator,
        },
        Spec {
            name: "sim",
            bin: sim_bin,
            args: sim_args,
            policy: sup.sim,
        },
    ]);
    let grace = Duration::from_millis(sup.grace_ms);
    let mut slots: Vec<Slot> = Vec::new();
    for spec in specs {
        match Slot::start(spec, &logs, &bar) {
            Ok(s) => slots.push(s),
            Err(e) => {
                stop_all(&mut slots, &|| {}, grace);
                return Err(e);
            }
        }
    }
    supervise::say(
        &bar,
        format!(
            "pids: {}",
            slots
                .iter()
                .map(|s| format!("{} {}", s.spec.name, s.proc.pid()))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    );

    let started = Instant::now();
    let mut progress = Progress {
        both_areas: (cfg.sim.flat_envs > 0 && cfg.sim.rough_envs > 0) || cfg.sim.mixed_envs > 0,
        ..Progress::default()
    };
    let mut interrupted = false;
    let mut failed: Option<String> = None;
    let mut swaps = 0u32;
    let mut sim_finished: Option<Instant> = None;
    loop {
        if let Some(s) = tele_rx.latest()? {
            progress.tick = *s.user_header();
        }
        if let Some(s) = terrain_rx.latest()? {
            progress.terrain = *s.user_header();
        }
        bar.set_position(progress.tick.env_steps.min(cfg.run.total_steps));
        bar.set_message(format!(
            "v{} success {:.0}% terrain {}",
            progress.tick.policy_version,
            100.0 * progress.success_rate(),
            progress
                .terrain_accuracy()
                .map_or("-".into(), |a| format!("{:.0}%", 100.0 * a))
        ));
        let may_restart = sim_finished.is_none();
        for slot in slots.iter_mut() {
            let name = slot.spec.name;
            match slot.watch(&logs, &bar, may_restart)? {
                Some(Event::Restarting { status, after }) => {
                    let cleaned = bus.cleanup_dead_nodes();
                    supervise::say(
                        &bar,
                        format!(
                            "{name} exited with {status}; restart {} of {} in {:.1} s ({cleaned} dead node(s) cleaned up)",
                            slot.restarts + 1,
                            slot.spec.policy.max_restarts,
                            after.as_secs_f64()
                        ),
                    );
                }
                Some(Event::Restarted { pid }) => {
                    supervise::say(&bar, format!("{name} restarted: pid {pid}"));
                }
                Some(Event::Exited(status)) if name == "sim" && status.success() => {
                    sim_finished = Some(Instant::now());
                }
                Some(Event::Exited(status)) if name == "estimator" && may_restart => {
                    // DESIGN §5: without estimates the sim keeps acting on its last ones.
                    bus.cleanup_dead_nodes();
                    supervise::say(
                        &bar,
                        format!(
                            "estimator exited with {status} for good; the sim keeps its last terrain estimates"
                        ),
                    );
                }
                Some(Event::Exited(status)) if !status.success() && failed.is_none() => {
                    failed = Some(format!("{name} exited with {status}"));
                }
                _ => {}
            }
        }
        if let Some(request) = swap_server.receive()? {
            let req = *request.payload();
            let name = PolicySlot::ALL[(req.slot as usize).min(2)].learner_name();
            let (ok, message) = match slots.iter_mut().find(|s| s.spec.name == name) {
                None => (false, format!("this run has no {name}")),
                Some(slot) => {
                    match swap::swap_learner(slot, &req, cfg, &dir, swaps + 1, &logs, &bar, grace) {
                        Ok(m) => {
                            swaps += 1;
                            bus.cleanup_dead_nodes();
                            (true, m)
                        }
                        Err(m) => (false, m),
                    }
                }
            };
            supervise::say(&bar, format!("swap-learner: {message}"));
            if let Err(e) = request.send_copy(SwapReply::new(ok, &message)) {
                supervise::say(&bar, format!("swap-learner: cannot reply: {e:?}"));
            }
        }
        let learner_alive = slots
            .iter()
            .any(|s| s.spec.name.starts_with("learner") && s.alive());
        // Once the sim is done the learner gets one grace period to learn from the last chunk.
        let learner_late = sim_finished.is_some_and(|t| t.elapsed() > grace);
        if failed.is_some() || (sim_finished.is_some() && (!learner_alive || learner_late)) {
            break;
        }
        if bus.node().wait(Duration::from_millis(100)).is_err() {
            interrupted = true;
            supervise::say(&bar, "interrupted: stopping the run".into());
            break;
        }
    }
    stop_all(
        &mut slots,
        &|| {
            if let Err(e) = ipc::request_shutdown(&control) {
                eprintln!("lavatube: {e}");
            }
        },
        grace,
    );
    bar.finish_and_clear();
    drop((tele_rx, terrain_rx, control, swap_server, bus));
    if let Err(e) = ipc::remove_run(&run_id) {
        eprintln!("lavatube: {e}");
    }

    let secs = started.elapsed().as_secs_f64();
    let summary = serde_json::json!({
        "run_id": run_id,
        "env_steps": progress.tick.env_steps,
        "wall_seconds": secs,
        "env_steps_per_second": progress.tick.env_steps as f64 / secs.max(1e-9),
        "episodes": progress.tick.episodes,
        "successes": progress.tick.successes,
        "success_rate": progress.success_rate(),
        "reach_seconds": progress.reach_seconds(cfg.sim.decision_dt()).map(|(m, s)| serde_json::json!({"mean": m, "std": s})),
        "policy_version": progress.tick.policy_version,
        "terrain_accuracy": progress.terrain_accuracy(),
        "pids": slots.iter().map(|s| (s.spec.name, s.proc.pid())).collect::<BTreeMap<_, _>>(),
        "exit": slots.iter().map(|s| (s.spec.name, s.proc.status.map(|s| s.to_string()))).collect::<BTreeMap<_, _>>(),
        "restarts": slots.iter().map(|s| (s.spec.name, s.restarts)).collect::<BTreeMap<_, _>>(),
        "learner_swaps": swaps,
    });
    let summary_path = dir.join("summary.json");
    std::fs::write(&summary_path, serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("cannot write {}", summary_path.display()))?;
    println!(
        "run {run_id}: {} env steps in {:.1} s ({:.0} steps/s), {} episodes, success {:.1}%, policy v{}, terrain accuracy {} → {}",
        progress.tick.env_steps,
        secs,
        progress.tick.env_steps as f64 / secs.max(1e-9),
        progress.tick.episodes,
        100.0 * progress.success_rate(),
        progress.tick.policy_version,
        progress
            .terrain_accuracy()
            .map_or("-".into(), |a| format!("{:.1}%", 100.0 * a)),
        dir.display()
    );
    if let Some(f) = failed {
        anyhow::bail!("{f}; logs in {}", logs.display());
    }
    Ok(!interrupted)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reach_time_comes_from_the_tick_sums() {
        // Two successes of 10 and 20 ticks at 0.1 s per tick: 1.5 s ± 0.5 s.
        let p = Progress {
            tick: TickHeader {
                successes: 2,
                reach_ticks: 30,
                reach_ticks_sq: 500,
                ..TickHeader::default()
            },
            ..Progress::default()
        };
        let (mean, std) = p.reach_seconds(0.1).expect("successes");
        assert!((mean - 1.5).abs() < 1e-12 && (std - 0.5).abs() < 1e-12);
        assert_eq!(Progress::default().reach_seconds(0.1), None);
    }
}
