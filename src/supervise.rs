//! Child processes of a run: spawned with their output prefixed and logged, watched, and
//! stopped by a ladder (shutdown request → grace period → SIGTERM → SIGKILL), always reaped.

use anyhow::Context;
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
        let mut log = std::fs::File::create(&log_path)
            .with_context(|| format!("cannot create {}", log_path.display()))?;
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

    fn signal(&self, sig: i32) {
        if let Ok(pid) = i32::try_from(self.child.id()) {
            // SAFETY: kill(2) on our own child's pid; it has not been reaped (status is None).
            unsafe {
                libc::kill(pid, sig);
            }
        }
    }

    /// Reaps the child and waits for its output to be copied.
    fn reap(&mut self) {
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
fn wait_all(procs: &mut [Proc], timeout: Duration, tick: &dyn Fn()) -> bool {
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
pub fn stop(procs: &mut [Proc], request: &dyn Fn(), grace: Duration) {
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

fn tracing_line(p: &Proc, what: &str) {
    eprintln!("lavatube: {} (pid {}) {what}", p.name, p.pid());
}
