//! `lavatube swap-learner`: replacing a run's learner while the simulator keeps stepping
//! (DESIGN §4). It sends a [`SwapRequest`] to the run's launcher over the `swap`
//! request-response service and prints the answer; the launcher's side is
//! `runtime::swap`.

use crate::error::UserError;
use crate::runtime::LAUNCHER_NODE;
use common::Config;
use common::config::PolicySlot;
use common::ipc::{self, Bus};
use common::wire::SwapRequest;
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
    /// The policy slot whose learner to replace: `general` or a terrain kind's (`flat`,
    /// `rough`, ...).
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
        .any(|n| n.alive && n.name == LAUNCHER_NODE);
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
