//! `lavatube run`: one training run (see [`Run`]), on one host or, with `--listen`, as the
//! learner host of a run across hosts; `lavatube join`: a sim host of such a run (DESIGN §9).
//! Both validate the config before anything starts, then run to the end and print a summary.

use crate::error::UserError;
use crate::runtime::{Host, ResumedConfig, Run, report_sweep};
use common::Config;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{SystemTime, UNIX_EPOCH};

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Config file (TOML). Without one: the built-in defaults, documented in
    /// `common/src/config/` (the README's main job is `configs/default.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run id: names the run directory and prefixes every shared-memory resource. Default: a new one.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: Option<String>,
    /// No progress bar (for logs and CI).
    #[arg(long)]
    pub quiet: bool,
    /// Show every log line of the run's processes, not only their warnings and errors (all
    /// of them are in `<run dir>/logs/` either way).
    #[arg(long)]
    pub verbose: bool,
    /// Go on with the stopped run in this directory (killed, or its machine restarted): its
    /// config and run id, each learner from its newest checkpoint (policy versions and the
    /// learning-rate schedule continue), the sim from the env steps that checkpoint learned
    /// from. What was learned after the last checkpoint is lost. With `--listen`, a learner
    /// host goes on, and its sim hosts reconnect by themselves.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = ["config", "run_id"])]
    pub resume: Option<PathBuf>,
    /// Be the learner host of a run across hosts: run the learners here, and a bridge that
    /// listens on this Zenoh endpoint (tcp/HOST:PORT) for sim hosts (`lavatube join`). Needs
    /// `net.key-file`.
    #[arg(long, value_name = "ENDPOINT", value_parser = common::cli::parse_endpoint)]
    pub listen: Option<String>,
}

#[derive(Debug, clap::Args)]
pub struct JoinArgs {
    /// Config file (TOML): the learner host's, with the same `net.key-file` contents.
    #[arg(long)]
    pub config: PathBuf,
    /// The learner host's Zenoh endpoint, tcp/HOST:PORT (`lavatube run --listen`).
    #[arg(long, value_name = "ENDPOINT", value_parser = common::cli::parse_endpoint)]
    pub connect: String,
    /// This host's source id, unique among the run's sim hosts; its chunks carry it. 1 ..= 65535.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65535))]
    pub source: u32,
    /// Run id on this host (the run directory's name). Default: a new one.
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: Option<String>,
    /// No progress bar (for logs and CI).
    #[arg(long)]
    pub quiet: bool,
    /// Show every log line of the run's processes, not only their warnings and errors (all
    /// of them are in `<run dir>/logs/` either way).
    #[arg(long)]
    pub verbose: bool,
}

/// A fresh run id: seconds since the epoch and the launcher's pid, in base 36-ish hex.
fn new_run_id() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!("r{secs:x}-{:x}", std::process::id())
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let host = |cfg: &Config| match args.listen.clone() {
        Some(listen) => across_hosts(cfg, Host::Learner { listen }),
        None => Ok(Host::Whole),
    };
    if let Some(dir) = &args.resume {
        let resumed = ResumedConfig::load(dir)?;
        let host = host(&resumed.cfg)?;
        report_sweep();
        let finished = Run::resume(&resumed, args.quiet)?
            .on_host(host)
            .verbose(args.verbose)
            .execute()?;
        return Ok(exit_code(!finished.interrupted));
    }
    let cfg = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let run_id = args.run_id.clone().unwrap_or_else(new_run_id);
    let host = host(&cfg)?;
    let completed = execute(&cfg, &run_id, &run_id, (args.quiet, args.verbose), host)?;
    Ok(exit_code(completed))
}

/// `lavatube join`: this host's sim, estimator and bridge, feeding the learner host.
pub fn join(args: JoinArgs) -> anyhow::Result<ExitCode> {
    let cfg = Config::load(&args.config)?;
    let host = across_hosts(
        &cfg,
        Host::Sim {
            connect: args.connect,
            source: args.source,
        },
    )?;
    let run_id = args.run_id.unwrap_or_else(new_run_id);
    let completed = execute(&cfg, &run_id, &run_id, (args.quiet, args.verbose), host)?;
    Ok(exit_code(completed))
}

/// `host`, once the config can run across hosts: it names a readable shared key.
fn across_hosts(cfg: &Config, host: Host) -> anyhow::Result<Host> {
    cfg.net
        .read_key()
        .map_err(|e| UserError(format!("a run across hosts: {e}")))?;
    Ok(host)
}

/// 130 (as a shell reports SIGINT) for a run stopped by Ctrl-C, else success.
fn exit_code(completed: bool) -> ExitCode {
    if completed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(130)
    }
}

/// Runs `host`'s part of `cfg` in `<run.out-dir>/<dir_name>/` to the end, its processes
/// meeting in the shared memory of run `run_id`, after removing what dead runs left.
/// Returns false when interrupted (Ctrl-C).
pub fn execute(
    cfg: &Config,
    dir_name: &str,
    run_id: &str,
    (quiet, verbose): (bool, bool),
    host: Host,
) -> anyhow::Result<bool> {
    report_sweep();
    let finished = Run::prepare(cfg, dir_name, run_id, quiet)?
        .on_host(host)
        .verbose(verbose)
        .execute()?;
    Ok(!finished.interrupted)
}
