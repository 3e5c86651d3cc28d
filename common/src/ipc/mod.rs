//! iceoryx2 plumbing shared by every process: one node per process with a per-run config,
//! the run's service names (`lavatube/<run>/<service>`), and typed slice channels, each a
//! publish-subscribe service paired with an event service so readers sleep until data comes.
//!
//! Ports of the `ipc` service type hold an `Rc`: keep all of a process's ports on one thread.

mod bus;
mod channel;
mod control;
mod files;
mod port;
mod swap;
#[cfg(test)]
mod tests;

pub use bus::Bus;
pub use channel::{
    Capacity, Channel, GYM_ACT, GYM_STEP, HOSTS, POLICY, ROLLOUT, TELEMETRY, TERRAIN,
};
pub use control::{CONTROL_SHUTDOWN, request_shutdown, shutdown_requested};
pub use files::{NodeInfo, list_nodes, remove_run, run_files, runs_with_files};
pub use port::{Received, Receiver, Sender};
pub use swap::{SwapClient, SwapServer};

use std::fmt::Debug;

pub type Svc = iceoryx2::prelude::ipc::Service;

/// An iceoryx2 operation failed; says which and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("shared memory: {what}: {reason}")]
pub struct IpcError {
    pub what: String,
    pub reason: String,
}

fn ipc_err(what: impl Into<String>) -> impl FnOnce(&dyn Debug) -> IpcError {
    let what = what.into();
    move |e| IpcError {
        what,
        reason: format!("{e:?}"),
    }
}

/// Checks a run id: 1–32 characters of `[A-Za-z0-9-]` (it becomes part of file names, where
/// `_` separates it from the rest).
pub fn validate_run_id(run: &str) -> Result<(), String> {
    let ok = !run.is_empty()
        && run.len() <= 32
        && run.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "run id `{run}` must be 1–32 characters of A-Z a-z 0-9 -"
        ))
    }
}

/// The file-name prefix of every shared-memory resource of run `run`, so one run's resources
/// are easy to find, list and remove, and two runs never collide.
pub fn resource_prefix(run: &str) -> String {
    format!("lavatube_{run}_")
}

/// The iceoryx2 config of a run, set in code (the config file is otherwise searched relative
/// to the current directory).
pub fn run_config(run: &str) -> Result<iceoryx2::config::Config, IpcError> {
    let mut cfg = iceoryx2::config::Config::default();
    cfg.global.prefix = resource_prefix(run)
        .as_str()
        .try_into()
        .map_err(|e| ipc_err("run prefix")(&e))?;
    Ok(cfg)
}
