//! One child process of the launcher: started with its output logged, polled without blocking,
//! signalled, and reaped with the CPU time and peak RSS the kernel counted for it.
//!
//! Every child asks the kernel for SIGTERM when the launcher dies (`PR_SET_PDEATHSIG`), so a
//! killed launcher never leaves its processes running: each treats SIGTERM as a stop
//! request (a learner checkpoints first). `waitid(…, WNOWAIT)` reads an exited child's
//! rusage while leaving it a zombie, so `std` still reaps it and keeps its exit status.

use super::{Lines, say};
use anyhow::Context;
use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufReader, Seek, SeekFrom};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What one process cost, from its rusage at exit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Usage {
    pub cpu_user_s: f64,
    pub cpu_system_s: f64,
    /// Peak resident set size (`ru_maxrss`), MiB.
    pub peak_rss_mib: f64,
}

impl Usage {
    pub fn cpu_s(&self) -> f64 {
        self.cpu_user_s + self.cpu_system_s
    }

    fn of(ru: &libc::rusage) -> Self {
        let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
        Self {
            cpu_user_s: secs(ru.ru_utime),
            cpu_system_s: secs(ru.ru_stime),
            // Linux reports kilobytes.
            peak_rss_mib: ru.ru_maxrss as f64 / 1024.0,
        }
    }
}

/// How a child's output is shown. Either way its stdout and stderr append straight to
/// `<log dir>/<name>.log` (a restarted process continues its predecessor's log), so the log
/// stays whole and the child never writes into a pipe that dies with the launcher.
#[derive(Clone, Copy)]
pub enum Output<'a> {
    /// Also shown (the lines [`Lines`] picks), prefixed by `[name]`, above the progress bar,
    /// by a thread that follows the log file.
    Relay(&'a ProgressBar, Lines),
    /// Only in the log: no thread competes with a measurement for the CPU.
    File,
}

/// A child process of the launcher.
pub struct Child {
    pub name: &'static str,
    child: std::process::Child,
    log: PathBuf,
    relay: Option<Relay>,
    /// Set once the child has exited and been reaped.
    exit: Option<(ExitStatus, Usage)>,
}

impl Child {
    /// Starts `bin args…` with its output sent to `output`, in `log_dir/<name>.log`.
    pub fn spawn(
        name: &'static str,
        bin: &Path,
        args: &[String],
        log_dir: &Path,
        output: Output,
    ) -> anyhow::Result<Self> {
        let log = log_dir.join(format!("{name}.log"));
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .with_context(|| format!("cannot open {}", log.display()))?;
        let start = file
            .metadata()
            .with_context(|| format!("cannot read {}", log.display()))?
            .len();
        let clone = || {
            file.try_clone()
                .with_context(|| format!("cannot open {}", log.display()))
        };
        let mut cmd = Command::new(bin);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(clone()?)
            .stderr(clone()?);
        let launcher = std::process::id();
        // SAFETY: the closure runs in the forked child before exec and calls only
        // async-signal-safe functions (prctl, getppid).
        unsafe {
            cmd.pre_exec(move || die_with_launcher(launcher));
        }
        let child = cmd
            .spawn()
            .with_context(|| format!("cannot start {}", bin.display()))?;
        let relay = match output {
            Output::Relay(bar, lines) => {
                Some(Relay::follow(name, &log, start, bar.clone(), lines)?)
            }
            Output::File => None,
        };
        Ok(Self {
            name,
            child,
            log,
            relay,
            exit: None,
        })
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn log(&self) -> &Path {
        &self.log
    }

    /// The exit status, once the child has exited and been reaped.
    pub fn status(&self) -> Option<ExitStatus> {
        self.exit.map(|(s, _)| s)
    }

    /// CPU time and peak RSS, once the child has exited.
    pub fn usage(&self) -> Option<Usage> {
        self.exit.map(|(_, u)| u)
    }

    /// Whether the child has exited; the first time it has, records its rusage and reaps it.
    pub fn poll(&mut self) -> anyhow::Result<Option<ExitStatus>> {
        if self.exit.is_none() {
            self.exit = self.wait_rusage(libc::WNOHANG)?;
        }
        Ok(self.status())
    }

    /// Waits for the child to exit (it must be on its way: the caller signalled it), then
    /// for its relayed output to be copied.
    pub fn reap(&mut self) {
        if self.exit.is_none() {
            match self.wait_rusage(0) {
                Ok(exit) => self.exit = exit,
                Err(e) => eprintln!("lavatube: {e:#}"),
            }
        }
        if let Some(r) = self.relay.take() {
            r.finish();
        }
    }

    /// Sends `sig` unless the child has been reaped (its pid may then be reused).
    pub fn signal(&self, sig: i32) {
        if self.exit.is_some() {
            return;
        }
        if let Ok(pid) = libc::pid_t::try_from(self.child.id()) {
            // SAFETY: kill(2) on our own child, not yet reaped (checked above).
            unsafe {
                libc::kill(pid, sig);
            }
        }
    }

    /// Polls until the child exits or `timeout` passes; whether it exited.
    pub fn wait_for(&mut self, timeout: Duration) -> anyhow::Result<bool> {
        let until = Instant::now() + timeout;
        while self.poll()?.is_none() {
            if Instant::now() >= until {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(true)
    }

    /// A one-line complaint when the child exited unsuccessfully.
    pub fn failure(&self) -> Option<String> {
        match self.status() {
            Some(status) if !status.success() => Some(format!(
                "{} exited with {status}; log: {}",
                self.name,
                self.log.display()
            )),
            _ => None,
        }
    }

    /// `waitid` with `WNOWAIT` for the rusage (`flags` adds `WNOHANG` for a poll), then
    /// `std`'s reap for the status. `None` while the child runs.
    fn wait_rusage(&mut self, flags: i32) -> anyhow::Result<Option<(ExitStatus, Usage)>> {
        let pid = libc::pid_t::try_from(self.child.id()).context("child pid out of range")?;
        // SAFETY: all-zero bytes are a valid siginfo_t and rusage (plain C structs).
        let (mut info, mut ru): (libc::siginfo_t, libc::rusage) =
            unsafe { (std::mem::zeroed(), std::mem::zeroed()) };
        loop {
            // SAFETY: waitid(2) on our own child, which only this type reaps (after this
            // call), with valid pointers to the two out-structs. The raw syscall because
            // glibc's wrapper has no rusage argument.
            let r = unsafe {
                libc::syscall(
                    libc::SYS_waitid,
                    libc::P_PID,
                    pid,
                    &raw mut info,
                    libc::WEXITED | libc::WNOWAIT | flags,
                    &raw mut ru,
                )
            };
            if r >= 0 {
                break;
            }
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(e)
                    .with_context(|| format!("cannot wait for {} (pid {pid})", self.name));
            }
        }
        // SAFETY: waitid filled `info` (or left it zeroed when the child is still running).
        if unsafe { info.si_pid() } == 0 {
            return Ok(None);
        }
        let status = self
            .child
            .wait()
            .with_context(|| format!("cannot reap {} (pid {pid})", self.name))?;
        Ok(Some((status, Usage::of(&ru))))
    }
}

/// A child still running when the launcher lets go of it (an error, Ctrl-C) is killed and
/// reaped, so a failed command leaves no process behind.
impl Drop for Child {
    fn drop(&mut self) {
        if self.exit.is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        if let Some(r) = self.relay.take() {
            r.finish();
        }
    }
}

/// In the forked child, before exec: SIGTERM when the launcher dies. If it died before the
/// request took effect, the child is already an orphan and does not start.
fn die_with_launcher(launcher: u32) -> std::io::Result<()> {
    // SAFETY: prctl(2) and getppid(2) on the calling process; both async-signal-safe.
    let (set, parent) = unsafe {
        (
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM),
            libc::getppid(),
        )
    };
    if set != 0 {
        return Err(std::io::Error::last_os_error());
    }
    if u32::try_from(parent).ok() != Some(launcher) {
        return Err(std::io::Error::other("the launcher exited during start-up"));
    }
    Ok(())
}

/// The thread that shows a child's log lines above the progress bar as they are written.
struct Relay {
    done: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Relay {
    /// How often the log file is looked at for new lines.
    const POLL: Duration = Duration::from_millis(50);

    /// Follows `log` from byte `start` (where this child's output begins).
    fn follow(
        name: &'static str,
        log: &Path,
        start: u64,
        bar: ProgressBar,
        lines: Lines,
    ) -> anyhow::Result<Self> {
        let mut file =
            std::fs::File::open(log).with_context(|| format!("cannot read {}", log.display()))?;
        file.seek(SeekFrom::Start(start))
            .with_context(|| format!("cannot read {}", log.display()))?;
        let done = Arc::new(AtomicBool::new(false));
        let finished = Arc::clone(&done);
        let thread = std::thread::spawn(move || {
            let mut reader = BufReader::new(file);
            let mut line = String::new();
            loop {
                // Read `done` before draining, so the last lines written before it was set
                // are shown.
                let last = finished.load(Ordering::Acquire);
                while reader.read_line(&mut line).is_ok_and(|n| n > 0) {
                    if !line.ends_with('\n') && !last {
                        // A line still being written: finish it on the next look.
                        break;
                    }
                    let text = line.trim_end_matches('\n');
                    if lines.shows(text) {
                        say(&bar, format!("[{name}] {text}"));
                    }
                    line.clear();
                }
                if last {
                    return;
                }
                std::thread::sleep(Self::POLL);
            }
        });
        Ok(Self { done, thread })
    }

    /// Shows what is left of the log, then stops following it.
    fn finish(self) {
        self.done.store(true, Ordering::Release);
        let _ = self.thread.join();
    }
}
