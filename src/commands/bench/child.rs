//! The processes of one measurement: output straight into a log file (no copying thread in
//! the launcher competing with them for the CPU), and on exit their CPU time and peak RSS as
//! the kernel counted them. `waitid(…, WNOWAIT)` reads an exited child's rusage while leaving
//! it a zombie, so `std` still reaps it and its exit status stays where `std` expects it.

use anyhow::Context;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
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

/// A child process of a measurement.
pub struct Child {
    pub name: &'static str,
    child: std::process::Child,
    pub log: PathBuf,
    /// Set once the child has exited and been reaped.
    pub exit: Option<(ExitStatus, Usage)>,
}

impl Child {
    /// Starts `bin args…` with stdout and stderr appended to `<log_dir>/<name>.log`.
    pub fn spawn(
        name: &'static str,
        bin: &Path,
        args: &[String],
        log_dir: &Path,
    ) -> anyhow::Result<Self> {
        let log = log_dir.join(format!("{name}.log"));
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .with_context(|| format!("cannot open {}", log.display()))?;
        let err = file
            .try_clone()
            .with_context(|| format!("cannot open {}", log.display()))?;
        let child = Command::new(bin)
            .args(args)
            .stdin(Stdio::null())
            .stdout(file)
            .stderr(err)
            .spawn()
            .with_context(|| format!("cannot start {}", bin.display()))?;
        Ok(Self {
            name,
            child,
            log,
            exit: None,
        })
    }

    /// Whether the child has exited; the first time it has, records its rusage and reaps it.
    pub fn poll(&mut self) -> anyhow::Result<bool> {
        if self.exit.is_some() {
            return Ok(true);
        }
        let pid = libc::pid_t::try_from(self.child.id()).context("child pid out of range")?;
        // SAFETY: all-zero bytes are a valid siginfo_t and rusage (plain C structs).
        let (mut info, mut ru): (libc::siginfo_t, libc::rusage) =
            unsafe { (std::mem::zeroed(), std::mem::zeroed()) };
        // SAFETY: waitid(2) on our own child, which only this function reaps (after this call),
        // with valid pointers to the two out-structs. The raw syscall because glibc's wrapper
        // has no rusage argument.
        let r = unsafe {
            libc::syscall(
                libc::SYS_waitid,
                libc::P_PID,
                pid,
                &mut info as *mut libc::siginfo_t,
                libc::WEXITED | libc::WNOHANG | libc::WNOWAIT,
                &mut ru as *mut libc::rusage,
            )
        };
        if r < 0 {
            return Err(std::io::Error::last_os_error())
                .with_context(|| format!("cannot wait for {} (pid {pid})", self.name));
        }
        // SAFETY: waitid filled `info` (or left it zeroed when the child is still running).
        if unsafe { info.si_pid() } == 0 {
            return Ok(false);
        }
        let status = self
            .child
            .wait()
            .with_context(|| format!("cannot reap {} (pid {pid})", self.name))?;
        self.exit = Some((status, Usage::of(&ru)));
        Ok(true)
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
        while !self.poll()? {
            if Instant::now() >= until {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(true)
    }

    /// A one-line complaint when the child exited unsuccessfully.
    pub fn failure(&self) -> Option<String> {
        match &self.exit {
            Some((status, _)) if !status.success() => Some(format!(
                "{} exited with {status}; log: {}",
                self.name,
                self.log.display()
            )),
            _ => None,
        }
    }
}

/// A child still running when its measurement is abandoned (an error, Ctrl-C) is killed and
/// reaped, so a failed bench leaves no process behind.
impl Drop for Child {
    fn drop(&mut self) {
        if self.exit.is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
