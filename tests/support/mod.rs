//! Shared by the end-to-end tests: running the launcher as a real process, with a watchdog
//! instead of a timing assertion.

use common::ipc::{self, Bus, Receiver};
use common::wire::{EnvTick, PolicyHeader, TickHeader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Kills the launcher if it has not finished in time.
const WATCHDOG: Duration = Duration::from_secs(900);

/// The repository root: configs and run directories are relative to it.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `lavatube ARGS` run to its end: its exit code, stdout and stderr.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn lavatube(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(args)
        .output()
        .expect("launcher runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A launcher started by a test, its output captured in a file (so a chatty run cannot
/// block on a full pipe).
pub struct Launched {
    pub child: Child,
    log_path: PathBuf,
}

impl Launched {
    /// `lavatube run --config CONFIG --run-id RUN_ID --quiet` from the repository root.
    pub fn start(config: &str, run_id: &str) -> Self {
        Self::run(&["--config", config, "--run-id", run_id], run_id)
    }

    /// `lavatube run ARGS… --quiet` from the repository root, its output in a file named
    /// after `tag`.
    pub fn run(args: &[&str], tag: &str) -> Self {
        Self::command(&["run"], args, tag)
    }

    /// `lavatube PREFIX… ARGS… --quiet` from the repository root (PREFIX may wrap the
    /// launcher, e.g. `ip netns exec NS`), its output in a file named after `tag`.
    pub fn command(prefix: &[&str], args: &[&str], tag: &str) -> Self {
        Self::spawn(prefix, args, tag, &["--quiet"])
    }

    /// `lavatube run ARGS…` as a person would start it (no `--quiet`), its output in a file:
    /// what it prints when not on a terminal.
    #[allow(dead_code)] // each test binary compiles this module; not all use every helper
    pub fn shown(args: &[&str], tag: &str) -> Self {
        Self::spawn(&["run"], args, tag, &[])
    }

    fn spawn(prefix: &[&str], args: &[&str], tag: &str, extra: &[&str]) -> Self {
        let log_path = std::env::temp_dir().join(format!("lavatube-test-{tag}.log"));
        let log = std::fs::File::create(&log_path).expect("log file");
        let (program, rest): (&str, Vec<&str>) = match prefix {
            [sub] => (env!("CARGO_BIN_EXE_lavatube"), vec![*sub]),
            [wrapper @ .., sub] => (
                wrapper[0],
                wrapper[1..]
                    .iter()
                    .copied()
                    .chain([env!("CARGO_BIN_EXE_lavatube"), *sub])
                    .collect(),
            ),
            [] => panic!("no subcommand"),
        };
        let child = Command::new(program)
            .args(rest)
            .args(args)
            .args(extra)
            .current_dir(root())
            .stdout(Stdio::from(log.try_clone().expect("log file")))
            .stderr(Stdio::from(log))
            .spawn()
            .expect("launcher starts");
        Self { child, log_path }
    }

    /// Waits for the launcher to exit; returns its exit code and everything it printed.
    pub fn wait(mut self) -> (i32, String) {
        let status = self.wait_status();
        let text = std::fs::read_to_string(&self.log_path).unwrap_or_default();
        let _ = std::fs::remove_file(&self.log_path);
        (status.code().unwrap_or(-1), text)
    }

    /// Stops the launcher as Ctrl-C would and waits; its exit code and what it printed.
    #[allow(dead_code)] // each test binary compiles this module; not all use every helper
    pub fn wait_interrupted(self) -> (i32, String) {
        // SAFETY: kill(2) on our own child, not yet reaped.
        unsafe {
            libc::kill(self.child.id() as i32, libc::SIGINT);
        }
        self.wait()
    }

    fn wait_status(&mut self) -> std::process::ExitStatus {
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("poll") {
                break status;
            }
            if started.elapsed() > WATCHDOG {
                self.child.kill().expect("kill");
                panic!("lavatube run did not finish within {WATCHDOG:?}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// A test that fails midway still stops its run: SIGINT, as Ctrl-C would, then the wait.
impl Drop for Launched {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            // SAFETY: kill(2) on our own child, not yet reaped.
            unsafe {
                libc::kill(self.child.id() as i32, libc::SIGINT);
            }
            self.wait_status();
        }
    }
}

/// `lavatube run --config CONFIG --run-id RUN_ID --quiet`, to the end.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn lavatube_run(config: &str, run_id: &str) -> (i32, String) {
    Launched::start(config, run_id).wait()
}

/// A test's ports on a run's bus, as any monitor would open them: the telemetry, and the
/// general learner's policies.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub struct Watch {
    pub bus: Bus,
    pub ticks: Receiver<EnvTick, TickHeader>,
    pub policies: Receiver<f32, PolicyHeader>,
}

#[allow(dead_code)]
impl Watch {
    /// Joins run `run` as node `name`.
    pub fn connect(run: &str, name: &str) -> Self {
        let bus = Bus::connect(run, name).expect("monitor node");
        Self {
            ticks: bus.receiver(&ipc::TELEMETRY, None).expect("telemetry"),
            policies: bus.receiver(&ipc::POLICY, Some("general")).expect("policy"),
            bus,
        }
    }
}

/// A run across hosts on this machine (DESIGN §9): a config with a shared key, and a free
/// loopback port for the learner host's bridge.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub struct AcrossHosts {
    pub config: String,
    pub endpoint: String,
    dir: PathBuf,
}

#[allow(dead_code)]
impl AcrossHosts {
    /// `base` (a config path from the repository root) with a `[net]` section added: a key
    /// file and `sim-hosts`; `tag` names its directory under target/e2e-runs.
    pub fn new(base: &str, tag: &str, sim_hosts: u32) -> Self {
        let dir = root().join("target/e2e-runs").join(format!("{tag}-hosts"));
        std::fs::create_dir_all(&dir).expect("hosts dir");
        let key = dir.join("run.key");
        std::fs::write(&key, b"a shared secret of this test run, 32+ bytes").expect("key");
        let text = std::fs::read_to_string(root().join(base)).expect("base config");
        let config = dir.join("config.toml");
        let net = format!(
            "\n[net]\nkey-file = {:?}\nsim-hosts = {sim_hosts}\n",
            key.display().to_string()
        );
        std::fs::write(&config, text + &net).expect("config");
        Self {
            config: config.display().to_string(),
            endpoint: format!("tcp/127.0.0.1:{}", free_port()),
            dir,
        }
    }

    /// `lavatube run --listen`: the learner host.
    pub fn learner_host(&self, run_id: &str) -> Launched {
        Launched::run(
            &[
                "--config",
                &self.config,
                "--run-id",
                run_id,
                "--listen",
                &self.endpoint,
            ],
            run_id,
        )
    }

    /// `lavatube join`: a sim host with source id `source`.
    pub fn sim_host(&self, run_id: &str, source: u32) -> Launched {
        let source = source.to_string();
        Launched::command(
            &["join"],
            &[
                "--config",
                &self.config,
                "--run-id",
                run_id,
                "--connect",
                &self.endpoint,
                "--source",
                &source,
            ],
            run_id,
        )
    }
}

impl Drop for AcrossHosts {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A TCP port on 127.0.0.1 that was free a moment ago.
#[allow(dead_code)]
pub fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    l.local_addr().expect("addr").port()
}

/// Whether `pid` still runs. A zombie (exited, not yet reaped by whoever adopted it) counts
/// as gone: it holds no memory, no shared-memory port, no CPU.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| {
        let state = s.rsplit(") ").next().and_then(|rest| rest.chars().next());
        !matches!(state, Some('Z' | 'X') | None)
    })
}

/// Waits until none of `processes` (name, pid) runs, failing once `patience` has passed
/// since `since`.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn until_gone(processes: &[(String, i32)], since: Instant, patience: Duration) {
    let mut left = processes.to_vec();
    while !left.is_empty() {
        assert!(
            since.elapsed() < patience,
            "still running {left:?} after the launcher died"
        );
        left.retain(|(_, pid)| running(*pid));
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The update numbers of a run directory's metrics.csv, in file order.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn update_numbers(run_dir: &Path) -> Vec<u64> {
    let metrics =
        std::fs::read_to_string(run_dir.join(common::run_dir::METRICS_CSV)).expect("metrics.csv");
    metrics
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next()?.parse().ok())
        .collect()
}

/// `lavatube status`'s section of run `run`.
#[allow(dead_code)] // each test binary compiles this module; not all use every helper
pub fn status_of(run: &str) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .arg("status")
        .output()
        .expect("lavatube status");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let from = text.find(&format!("run {run}:")).unwrap_or(text.len());
    let section = &text[from..];
    let end = section
        .get(1..)
        .and_then(|rest| rest.find("\nrun "))
        .map_or(section.len(), |i| i + 1);
    section[..end].to_string()
}
