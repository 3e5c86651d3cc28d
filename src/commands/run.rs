//! `lavatube run`: one training run. Validates the config before anything starts, creates the
//! run directory, starts learner, estimator and simulator, shows progress from the run's own
//! telemetry, stops everything on Ctrl-C or failure, and prints a summary.

use super::UserError;
use crate::supervise::{self, Proc};
use anyhow::Context;
use common::Config;
use common::ipc::{self, Bus};
use common::wire::{EnvTick, TerrainEstimate, TerrainHeader, TickHeader};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How long a process gets to stop on request before SIGTERM, and again before SIGKILL.
const GRACE: Duration = Duration::from_secs(5);

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Config file (TOML). Defaults to the built-in defaults (`configs/default.toml` spells them out).
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
    /// Both areas have envs: only then does scoring a two-class terrain estimate mean anything.
    both_areas: bool,
}

impl Progress {
    fn success_rate(&self) -> f64 {
        self.tick.successes as f64 / self.tick.episodes.max(1) as f64
    }

    fn terrain_accuracy(&self) -> Option<f64> {
        (self.both_areas && self.terrain.scored > 0)
            .then(|| self.terrain.correct as f64 / self.terrain.scored as f64)
    }
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let cfg = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let bins = [
        supervise::locate("learner-proc")?,
        supervise::locate("estimator-proc")?,
        supervise::locate("sim-proc")?,
    ];
    let run_id = args.run_id.clone().unwrap_or_else(new_run_id);
    let dir = cfg.run.out_dir.join(&run_id);
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

    let bar = if args.quiet {
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
            "run {run_id}: {} flat + {} rough envs, {:?} mode → {}",
            cfg.sim.flat_envs,
            cfg.sim.rough_envs,
            cfg.run.mode,
            dir.display()
        ),
    );

    let bus = Bus::connect(&run_id, "launcher")?;
    let control = bus.control_notifier()?;
    let tele_rx = bus.receiver::<EnvTick, TickHeader>(&ipc::TELEMETRY, None)?;
    let terrain_rx = bus.receiver::<TerrainEstimate, TerrainHeader>(&ipc::TERRAIN, None)?;

    let common_args = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
        v.extend([
            "--config".into(),
            cfg_path.display().to_string(),
            "--run-id".into(),
            run_id.clone(),
        ]);
        v
    };
    let specs: [(&'static str, Vec<String>); 3] = [
        ("learner", {
            let mut a = common_args(&["serve"]);
            a.extend(["--out".into(), dir.display().to_string()]);
            a
        }),
        ("estimator", common_args(&["serve"])),
        ("sim", common_args(&[])),
    ];
    let mut procs: Vec<Proc> = Vec::new();
    for ((name, a), bin) in specs.into_iter().zip(&bins) {
        match Proc::spawn(name, bin, &a, &logs, &bar) {
            Ok(p) => procs.push(p),
            Err(e) => {
                supervise::stop(&mut procs, &|| {}, GRACE);
                return Err(e);
            }
        }
    }
    supervise::say(
        &bar,
        format!(
            "pids: {}",
            procs
                .iter()
                .map(|p| format!("{} {}", p.name, p.pid()))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    );

    let started = Instant::now();
    let mut progress = Progress {
        both_areas: cfg.sim.flat_envs > 0 && cfg.sim.rough_envs > 0,
        ..Progress::default()
    };
    let mut interrupted = false;
    let mut failed: Option<String> = None;
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
        for p in procs.iter_mut() {
            if let Some(st) = p.poll()
                && !st.success()
                && failed.is_none()
            {
                failed = Some(format!("{} exited with {st}", p.name));
            }
        }
        let sim_done = procs.iter().any(|p| p.name == "sim" && p.status.is_some());
        let learner_done = procs
            .iter()
            .any(|p| p.name == "learner" && p.status.is_some());
        if failed.is_some() || (sim_done && learner_done) {
            break;
        }
        if bus.node().wait(Duration::from_millis(100)).is_err() {
            interrupted = true;
            supervise::say(&bar, "interrupted: stopping the run".into());
            break;
        }
    }
    supervise::stop(
        &mut procs,
        &|| {
            if let Err(e) = ipc::request_shutdown(&control) {
                eprintln!("lavatube: {e}");
            }
        },
        GRACE,
    );
    bar.finish_and_clear();
    drop((tele_rx, terrain_rx, control, bus));
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
        "success_rate": progress.success_rate(),
        "policy_version": progress.tick.policy_version,
        "terrain_accuracy": progress.terrain_accuracy(),
        "pids": procs.iter().map(|p| (p.name, p.pid())).collect::<std::collections::BTreeMap<_, _>>(),
        "exit": procs.iter().map(|p| (p.name, p.status.map(|s| s.to_string()))).collect::<std::collections::BTreeMap<_, _>>(),
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
    Ok(if interrupted {
        ExitCode::from(130)
    } else {
        ExitCode::SUCCESS
    })
}
