//! One process of a run under its restart policy (`[supervise]`, DESIGN §4): watched every
//! loop of the run, started again after a backoff when its policy says so.

use super::{Child, Lines, Output, Role};
use common::config::RestartPolicy;
use indicatif::ProgressBar;
use std::collections::VecDeque;
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
    /// The process exited and will be started again after `after`; `recent` restarts
    /// (this one included) fall within the policy's window.
    Restarting {
        status: ExitStatus,
        after: Duration,
        recent: u32,
    },
    /// The process was started again.
    Restarted { pid: u32 },
    /// The process exited for good.
    Exited(ExitStatus),
}

/// One process of a run and its restart bookkeeping.
pub struct Supervised {
    pub spec: Spec,
    pub child: Child,
    /// Restarts over the run.
    pub restarts: u32,
    /// When the restarts within the policy's window happened, oldest first.
    recent: VecDeque<Instant>,
    restart_at: Option<Instant>,
    /// The current process's exit has been reported.
    seen_exit: bool,
    /// Which of its log lines are shown.
    lines: Lines,
}

impl Supervised {
    pub fn start(spec: Spec, logs: &Path, bar: &ProgressBar, lines: Lines) -> anyhow::Result<Self> {
        let child = spawn(&spec, logs, bar, lines)?;
        Ok(Self {
            spec,
            child,
            restarts: 0,
            recent: VecDeque::new(),
            restart_at: None,
            seen_exit: false,
            lines,
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
                self.recent.push_back(Instant::now());
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
        let recent = self.recent_restarts(Instant::now());
        if may_restart && self.spec.policy.restarts_after(status.success(), recent) {
            let after = self.spec.policy.backoff(recent);
            self.restart_at = Some(Instant::now() + after);
            return Ok(Some(Event::Restarting {
                status,
                after,
                recent: recent + 1,
            }));
        }
        Ok(Some(Event::Exited(status)))
    }

    /// Restarts within the policy's window ending `now` (all of them without a window).
    fn recent_restarts(&mut self, now: Instant) -> u32 {
        if let Some(window) = self.spec.policy.window() {
            while self
                .recent
                .front()
                .is_some_and(|t| now.duration_since(*t) >= window)
            {
                self.recent.pop_front();
            }
        }
        u32::try_from(self.recent.len()).unwrap_or(u32::MAX)
    }

    /// Starts the process again with the spec's (possibly changed) arguments; the previous
    /// one must have exited.
    pub fn replace(&mut self, logs: &Path, bar: &ProgressBar) -> anyhow::Result<()> {
        self.child.reap();
        self.child = spawn(&self.spec, logs, bar, self.lines)?;
        self.seen_exit = false;
        Ok(())
    }
}

fn spawn(spec: &Spec, logs: &Path, bar: &ProgressBar, lines: Lines) -> anyhow::Result<Child> {
    Child::spawn(
        spec.role.name(),
        &spec.bin,
        &spec.args,
        logs,
        Output::Relay(bar, lines),
    )
}
