//! One process of a run under its restart policy (`[supervise]`, DESIGN §4): watched every
//! loop of the run, started again after a backoff when its policy says so.

use super::{Child, Output, Role};
use common::config::RestartPolicy;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::time::{Duration, Instant};

/// How to start one process of a run, and when to start it again.
#[derive(Debug, Clone)]
pub struct Spec {
    pub role: Role,
    pub bin: PathBuf,
    pub args: Vec<String>,
    pub policy: RestartPolicy,
}

/// What [`Supervised::watch`] saw.
#[derive(Debug)]
pub enum Event {
    /// The process exited and will be started again after `after`.
    Restarting { status: ExitStatus, after: Duration },
    /// The process was started again.
    Restarted { pid: u32 },
    /// The process exited for good.
    Exited(ExitStatus),
}

/// One process of a run and its restart bookkeeping.
pub struct Supervised {
    pub spec: Spec,
    pub child: Child,
    pub restarts: u32,
    restart_at: Option<Instant>,
    /// The current process's exit has been reported.
    seen_exit: bool,
}

impl Supervised {
    pub fn start(spec: Spec, logs: &Path, bar: &ProgressBar) -> anyhow::Result<Self> {
        let child = spawn(&spec, logs, bar)?;
        Ok(Self {
            spec,
            child,
            restarts: 0,
            restart_at: None,
            seen_exit: false,
        })
    }

    pub fn role(&self) -> Role {
        self.spec.role
    }

    /// Running, or about to be restarted.
    pub fn alive(&self) -> bool {
        !self.seen_exit || self.restart_at.is_some()
    }

    /// Polls the process and applies the restart policy; `may_restart` is false once the run
    /// is ending. Call every loop iteration.
    pub fn watch(
        &mut self,
        logs: &Path,
        bar: &ProgressBar,
        may_restart: bool,
    ) -> anyhow::Result<Option<Event>> {
        if let Some(at) = self.restart_at {
            if !may_restart {
                self.restart_at = None;
            } else if Instant::now() >= at {
                self.restart_at = None;
                self.replace(logs, bar)?;
                self.restarts += 1;
                return Ok(Some(Event::Restarted {
                    pid: self.child.pid(),
                }));
            }
            return Ok(None);
        }
        if self.seen_exit {
            return Ok(None);
        }
        let Some(status) = self.child.poll()? else {
            return Ok(None);
        };
        self.seen_exit = true;
        if may_restart
            && self
                .spec
                .policy
                .restarts_after(status.success(), self.restarts)
        {
            let after = self.spec.policy.backoff(self.restarts);
            self.restart_at = Some(Instant::now() + after);
            return Ok(Some(Event::Restarting { status, after }));
        }
        Ok(Some(Event::Exited(status)))
    }

    /// Starts the process again with the spec's (possibly changed) arguments; the previous
    /// one must have exited.
    pub fn replace(&mut self, logs: &Path, bar: &ProgressBar) -> anyhow::Result<()> {
        self.child.reap();
        self.child = spawn(&self.spec, logs, bar)?;
        self.seen_exit = false;
        Ok(())
    }
}

fn spawn(spec: &Spec, logs: &Path, bar: &ProgressBar) -> anyhow::Result<Child> {
    Child::spawn(
        spec.role.name(),
        &spec.bin,
        &spec.args,
        logs,
        Output::Relay(bar),
    )
}
