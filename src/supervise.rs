//! Child processes of a run: spawned with their output prefixed and logged, watched and
//! restarted by their [`RestartPolicy`], and stopped by a ladder (shutdown request → grace
//! period → SIGTERM → SIGKILL), always reaped.

use anyhow::Context;
use common::config::RestartPolicy;
use indicatif::ProgressBar;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Prints a line above the progress bar, or to stderr when the bar is hidden (not a terminal,
/// `--quiet`), where indicatif would drop it.
pub fn say(bar: &ProgressBar, line: String) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}

/// A process binary, looked up beside the launcher's own executable.
pub fn locate(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot find the launcher's own executable")?;
    let dir = exe
        .parent()
        .context("the launcher's executable has no directory")?;
    // Test binaries live one level down, in deps/.
    for d in [dir, dir.parent().unwrap_or(dir)] {
        let p = d.join(name);
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(super::commands::UserError(format!(
        "cannot find `{name}` beside {}: build the workspace first (cargo build --release --workspace)",
        dir.display()
    ))
    .into())
}

/// One supervised child.
pub struct Proc {
    pub name: &'static str,
    child: Child,
    logger: Option<JoinHandle<()>>,
    pub status: Option<ExitStatus>,
}

impl Proc {
    /// Spawns `bin args…`, copying each output line to `log_dir/<name>.log` and, prefixed by
    /// `[name]`, above the progress bar.
    pub fn spawn(
        name: &'static str,
        bin: &Path,
        args: &[String],
        log_dir: &Path,
        bar: &ProgressBar,
    ) -> anyhow::Result<Self> {
        let mut child = Command::new(bin)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot start {}", bin.display()))?;
        let log_path = log_dir.join(format!("{name}.log"));
        // Appended to: a restarted process continues its predecessor's log.
        let mut log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .with_context(|| format!("cannot open {}", log_path.display()))?;
        let (out, err) = (child.stdout.take(), child.stderr.take());
        let bar = bar.clone();
        let logger = std::thread::spawn(move || {
            let (tx, rx) = std::sync::mpsc::channel::<String>();
            let readers: Vec<_> = [
                out.map(|o| Box::new(o) as Box<dyn std::io::Read + Send>),
                err.map(|e| Box::new(e) as _),
            ]
            .into_iter()
            .flatten()
            .map(|r| {
                let tx = tx.clone();
                std::thread::spawn(move || {
                    for line in BufReader::new(r).lines().map_while(Result::ok) {
                        if tx.send(line).is_err() {
                            break;
                        }
                    }
                })
            })
            .collect();
            drop(tx);
            for line in rx {
                let _ = writeln!(log, "{line}");
                say(&bar, format!("[{name}] {line}"));
            }
            for r in readers {
                let _ = r.join();
            }
        });
        Ok(Self {
            name,
            child,
            logger: Some(logger),
            status: None,
        })
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Polls the child; records and returns its exit status once it has exited.
    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().ok().flatten();
        }
        self.status
    }

    /// Sends `sig` unless the child has been reaped (its pid may then be reused).
    pub fn signal(&self, sig: i32) {
        if self.status.is_some() {
            return;
        }
        if let Ok(pid) = i32::try_from(self.child.id()) {
            // SAFETY: kill(2) on our own child's pid; it has not been reaped (checked above).
            unsafe {
                libc::kill(pid, sig);
            }
        }
    }

    /// Reaps the child and waits for its output to be copied.
    pub fn reap(&mut self) {
        if self.status.is_none() {
            self.status = self.child.wait().ok();
        }
        if let Some(l) = self.logger.take() {
            let _ = l.join();
        }
    }
}

/// Waits until every child in `procs` has exited or `timeout` passes, calling `tick` every
/// 100 ms meanwhile.
fn wait_all(procs: &mut [&mut Proc], timeout: Duration, tick: &dyn Fn()) -> bool {
    let until = Instant::now() + timeout;
    let mut next_tick = Instant::now();
    loop {
        if procs.iter_mut().all(|p| p.poll().is_some()) {
            return true;
        }
        let now = Instant::now();
        if now >= until {
            return false;
        }
        if now >= next_tick {
            tick();
            next_tick = now + Duration::from_millis(100);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The stop ladder: `request` (a shutdown event; repeated every 100 ms, since an event sent
/// before a child has connected is not delivered to it), then SIGTERM after `grace`, then
/// SIGKILL after `grace` again. Every child is reaped before this returns.
pub fn stop(procs: &mut [&mut Proc], request: &dyn Fn(), grace: Duration) {
    if !wait_all(procs, grace, request) {
        for p in procs.iter_mut().filter(|p| p.status.is_none()) {
            tracing_line(p, "did not stop on request: SIGTERM");
            p.signal(libc::SIGTERM);
        }
        if !wait_all(procs, grace, &|| {}) {
            for p in procs.iter_mut().filter(|p| p.status.is_none()) {
                tracing_line(p, "ignored SIGTERM: SIGKILL");
                p.signal(libc::SIGKILL);
            }
        }
    }
    for p in procs.iter_mut() {
        p.reap();
    }
}

/// Stops one process by SIGTERM first (the processes treat it as a stop request: a learner
/// checkpoints and exits), then the rest of the ladder.
pub fn terminate(p: &mut Proc, grace: Duration) {
    let pid = p.pid();
    stop(
        &mut [p],
        &|| {
            if let Ok(pid) = i32::try_from(pid) {
                // SAFETY: kill(2) on our own child, which `stop` reaps only after this call
                // returns, so the pid cannot have been reused.
                unsafe {
                    libc::kill(pid, libc::SIGTERM);
                }
            }
        },
        grace,
    );
}

fn tracing_line(p: &Proc, what: &str) {
    eprintln!("lavatube: {} (pid {}) {what}", p.name, p.pid());
}

/// How to start one process of a run, and when to start it again.
#[derive(Debug, Clone)]
pub struct Spec {
    pub name: &'static str,
    pub bin: PathBuf,
    pub args: Vec<String>,
    pub policy: RestartPolicy,
}

/// What [`Slot::watch`] saw.
#[derive(Debug)]
pub enum Event {
    /// The process exited and will be started again after `after`.
    Restarting { status: ExitStatus, after: Duration },
    /// The process was started again.
    Restarted { pid: u32 },
    /// The process exited for good.
    Exited(ExitStatus),
}

/// One process of a run under its restart policy.
pub struct Slot {
    pub spec: Spec,
    pub proc: Proc,
    pub restarts: u32,
    restart_at: Option<Instant>,
    /// The current process's exit has been reported.
    seen_exit: bool,
}

impl Slot {
    pub fn start(spec: Spec, logs: &Path, bar: &ProgressBar) -> anyhow::Result<Self> {
        let proc = Proc::spawn(spec.name, &spec.bin, &spec.args, logs, bar)?;
        Ok(Self {
            spec,
            proc,
            restarts: 0,
            restart_at: None,
            seen_exit: false,
        })
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
                    pid: self.proc.pid(),
                }));
            }
            return Ok(None);
        }
        if self.seen_exit {
            return Ok(None);
        }
        let Some(status) = self.proc.poll() else {
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
        self.proc.reap();
        self.proc = Proc::spawn(self.spec.name, &self.spec.bin, &self.spec.args, logs, bar)?;
        self.seen_exit = false;
        Ok(())
    }
}
