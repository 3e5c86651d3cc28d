//! Replacing a run's learner while the simulator keeps stepping (DESIGN §4).
//!
//! `lavatube swap-learner` sends a [`SwapRequest`] to the run's launcher over the `swap`
//! request-response service; the launcher checks the new learner before touching the old one
//! (`learner-proc serve --check`: config, checkpoint and network shape), stops the old one
//! with SIGTERM (it checkpoints and exits), cleans up after it and starts the new one, which
//! resumes the run's newest checkpoint (or the named one) and continues the version sequence.

use super::UserError;
use crate::commands::run::learner_args;
use crate::supervise::{self, Slot};
use common::Config;
use common::config::PolicySlot;
use common::ipc::{self, Bus};
use common::wire::SwapRequest;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub struct SwapArgs {
    /// The run whose learner to replace (its launcher must be running).
    #[arg(long, value_parser = common::cli::parse_run_id)]
    pub run_id: String,
    /// A config for the new learner; only its [ppo], [estimator] and [supervise] sections may
    /// differ from the running one. Default: the running config.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Start from this checkpoint instead of the run's newest.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// The policy slot whose learner to replace: general, flat or rough.
    #[arg(long, default_value = "general", value_parser = PolicySlot::parse)]
    pub slot: PolicySlot,
    /// Give up waiting for the launcher's answer after this many seconds.
    #[arg(long, default_value_t = 120)]
    pub timeout_secs: u64,
}

/// An absolute path to an existing file, or a user error naming the option.
fn existing(option: &str, p: &Path) -> anyhow::Result<String> {
    let abs = std::fs::canonicalize(p)
        .map_err(|e| UserError(format!("{option} {}: {e}", p.display())))?;
    if !abs.is_file() {
        return Err(UserError(format!("{option} {}: not a file", p.display())).into());
    }
    Ok(abs.display().to_string())
}

/// `lavatube swap-learner`: asks the run's launcher to swap, prints its answer.
pub fn swap_learner_command(args: SwapArgs) -> anyhow::Result<ExitCode> {
    let config = match &args.config {
        Some(p) => {
            Config::load(p)?;
            existing("--config", p)?
        }
        None => String::new(),
    };
    let checkpoint = match &args.checkpoint {
        Some(p) => existing("--checkpoint", p)?,
        None => String::new(),
    };
    let request =
        SwapRequest::new(args.slot.index() as u32, &config, &checkpoint).map_err(UserError)?;
    let launcher_alive = ipc::list_nodes(&args.run_id)?
        .iter()
        .any(|n| n.alive && n.name == super::run::LAUNCHER_NODE);
    if !launcher_alive {
        return Err(UserError(format!(
            "run `{}` has no running launcher (see `lavatube status`)",
            args.run_id
        ))
        .into());
    }
    let bus = Bus::connect(&args.run_id, "swap-learner")?;
    let client = bus.swap_client()?;
    let pending = client
        .send_copy(request)
        .map_err(|e| anyhow::anyhow!("cannot send the swap request: {e:?}"))?;
    let until = Instant::now() + Duration::from_secs(args.timeout_secs);
    while Instant::now() < until {
        if let Some(reply) = pending
            .receive()
            .map_err(|e| anyhow::anyhow!("cannot receive the swap reply: {e:?}"))?
        {
            let message = reply.payload().message();
            return if reply.payload().ok == 1 {
                println!("{message}");
                Ok(ExitCode::SUCCESS)
            } else {
                Err(UserError(format!("swap refused: {message}")).into())
            };
        }
        if bus.node().wait(Duration::from_millis(50)).is_err() {
            break;
        }
    }
    anyhow::bail!(
        "no answer from the launcher of run `{}` within {} s",
        args.run_id,
        args.timeout_secs
    )
}

/// Sections that differ between the running config and a new learner's, which must not: the
/// sim keeps running with the old ones, and the learner's batch shape follows from them.
fn fixed_sections_differ(running: &Config, new: &Config) -> Vec<&'static str> {
    let mut differ = Vec::new();
    if running.run != new.run {
        differ.push("[run]");
    }
    if running.sim != new.sim {
        differ.push("[sim]");
    }
    differ
}

/// The launcher's side: replaces the learner in `slot` as `req` asks. Returns what happened,
/// or why nothing did (the old learner then still runs).
#[allow(clippy::too_many_arguments)]
pub fn swap_learner(
    slot: &mut Slot,
    req: &SwapRequest,
    running: &Config,
    run_dir: &Path,
    n: u32,
    logs: &Path,
    bar: &ProgressBar,
    grace: Duration,
) -> Result<String, String> {
    // The running learner's arguments: `serve … --out DIR [--checkpoint P]`.
    let args = &slot.spec.args;
    let Some(at) = args.iter().position(|a| a == "--out") else {
        return Err(format!("{} was not started with --out", slot.spec.name));
    };
    let out = PathBuf::from(args.get(at + 1).cloned().unwrap_or_default());
    let mut join = args[..at].to_vec();
    let config = req.config();
    if !config.is_empty() {
        let new = Config::load(Path::new(&config)).map_err(|e| e.to_string())?;
        let differ = fixed_sections_differ(running, &new);
        if !differ.is_empty() {
            return Err(format!(
                "{config} differs from the running config in {}: a new learner may change only [ppo], [estimator] and [supervise]",
                differ.join(", ")
            ));
        }
        let resolved = run_dir.join(format!("learner-config-{n}.toml"));
        std::fs::write(&resolved, new.to_toml())
            .map_err(|e| format!("cannot write {}: {e}", resolved.display()))?;
        if let Some(i) = join.iter().position(|a| a == "--config") {
            join[i + 1] = resolved.display().to_string();
        }
    }
    let checkpoint = req.checkpoint();
    let checkpoint = (!checkpoint.is_empty()).then(|| PathBuf::from(checkpoint));
    let first_args = learner_args(&join, &out, checkpoint.as_deref());
    let check = std::process::Command::new(&slot.spec.bin)
        .args(&first_args)
        .arg("--check")
        .output()
        .map_err(|e| format!("cannot run {}: {e}", slot.spec.bin.display()))?;
    let said = String::from_utf8_lossy(&check.stderr);
    let last = said.lines().last().unwrap_or("").trim().to_string();
    if !check.status.success() {
        return Err(last);
    }
    let old = slot.proc.pid();
    supervise::terminate(&mut slot.proc, grace);
    slot.spec.args = first_args;
    slot.replace(logs, bar).map_err(|e| format!("{e:#}"))?;
    // Later restarts resume the run's newest checkpoint, which the new learner writes.
    slot.spec.args = learner_args(&join, &out, None);
    Ok(format!(
        "learner swapped: pid {old} -> {} ({}; {})",
        slot.proc.pid(),
        if config.is_empty() {
            "same config".to_string()
        } else {
            config
        },
        String::from_utf8_lossy(&check.stdout).trim()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_learner_sections_may_change() {
        let running = Config::default();
        let mut new = running.clone();
        new.ppo.learning_rate = 1e-4;
        new.supervise.grace_ms = 1000;
        assert!(fixed_sections_differ(&running, &new).is_empty());
        new.sim.flat_envs += 1;
        new.run.seed += 1;
        assert_eq!(fixed_sections_differ(&running, &new), ["[run]", "[sim]"]);
    }
}
