//! DESIGN §3–§5 under faults, with real processes: an async run on
//! tests/fixtures/survival.toml whose learner is killed mid-update, restarted on a truncated
//! checkpoint and swapped for one with another learning rate, whose estimator is killed, and
//! which a process speaking another wire version tries to join; through all of it the
//! simulator keeps stepping. The test watches the run through shared memory, as any monitor
//! would.

use common::Transition;
use common::ipc::{self, Bus, Receiver};
use common::wire::{EnvTick, PolicyHeader, RolloutHeader, TickHeader};
use iceoryx2::prelude::ZeroCopySend;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/survival.toml";
/// Long enough for a debug-build learner to start and do an update.
const PATIENCE: Duration = Duration::from_secs(120);

/// What the test sees of the run through shared memory.
struct Monitor {
    run: String,
    bus: Bus,
    ticks: Receiver<EnvTick, TickHeader>,
    policies: Receiver<f32, PolicyHeader>,
    rollouts: Receiver<Transition, RolloutHeader>,
    /// (when, sim tick) of every telemetry message seen.
    tick_log: Vec<(Instant, u64)>,
    /// (version, learner pid) of every policy message, in order.
    policy_log: Vec<(u32, u32)>,
    chunks: u64,
}

impl Monitor {
    fn connect(run: &str) -> Self {
        let bus = Bus::connect(run, "monitor").expect("monitor node");
        Self {
            ticks: bus.receiver(&ipc::TELEMETRY, None).expect("telemetry"),
            policies: bus.receiver(&ipc::POLICY, Some("general")).expect("policy"),
            rollouts: bus.receiver(&ipc::ROLLOUT, None).expect("rollout"),
            run: run.to_string(),
            bus,
            tick_log: Vec::new(),
            policy_log: Vec::new(),
            chunks: 0,
        }
    }

    fn pump(&mut self) {
        while let Some(s) = self.ticks.try_recv().expect("telemetry") {
            self.tick_log.push((Instant::now(), s.user_header().tick));
        }
        while let Some(s) = self.policies.try_recv().expect("policy") {
            let h = s.user_header();
            self.policy_log.push((h.version, h.learner));
        }
        while self.rollouts.try_recv().expect("rollout").is_some() {
            self.chunks += 1;
        }
    }

    /// Pumps until `done` holds; panics naming `what` after [`PATIENCE`].
    fn until(&mut self, what: &str, done: impl Fn(&Self) -> bool) {
        let give_up = Instant::now() + PATIENCE;
        while !done(self) {
            assert!(Instant::now() < give_up, "gave up waiting for {what}");
            self.ticks.wait(Duration::from_millis(5)).expect("wait");
            self.pump();
        }
    }

    fn watch(&mut self, d: Duration) {
        let end = Instant::now() + d;
        self.until("the clock", |_| Instant::now() >= end);
    }

    /// Sim ticks per second between two instants, from the telemetry seen in between.
    fn rate(&self, from: Instant, to: Instant) -> f64 {
        let inside: Vec<_> = self
            .tick_log
            .iter()
            .filter(|(t, _)| *t >= from && *t <= to)
            .collect();
        let (Some(a), Some(b)) = (inside.first(), inside.last()) else {
            return 0.0;
        };
        (b.1 - a.1) as f64 / (b.0 - a.0).as_secs_f64().max(1e-9)
    }

    /// The longest wait between two received ticks from `from` to `to`.
    fn longest_pause(&self, from: Instant, to: Instant) -> Duration {
        let inside: Vec<Instant> = self
            .tick_log
            .iter()
            .map(|(t, _)| *t)
            .filter(|t| *t >= from && *t <= to)
            .collect();
        inside
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(to - from)
    }

    /// The sim's newest tick and the CPU time its process has used, now.
    fn progress(&mut self) -> Progress {
        self.pump();
        Progress {
            at: Instant::now(),
            tick: self.last_tick(),
            cpu: cpu_time(self.pid("sim")),
        }
    }

    fn last_tick(&self) -> u64 {
        self.tick_log.last().map_or(0, |t| t.1)
    }

    /// The pid of the run's live process `name`, if its node is up.
    fn live_pid(&self, name: &str) -> Option<i32> {
        ipc::list_nodes(&self.run)
            .expect("nodes")
            .into_iter()
            .find(|n| n.alive && n.name == name)
            .map(|n| n.pid)
    }

    /// The pid of the run's live process `name`.
    fn pid(&self, name: &str) -> i32 {
        self.live_pid(name)
            .unwrap_or_else(|| panic!("no live {name}"))
    }

    /// Policy messages of learner `pid`.
    fn versions_of(&self, pid: i32) -> Vec<u32> {
        self.policy_log
            .iter()
            .filter(|(_, l)| *l as i32 == pid)
            .map(|(v, _)| *v)
            .collect()
    }
}

/// Where the sim stood at one instant: its tick and its CPU time.
struct Progress {
    at: Instant,
    tick: u64,
    cpu: Duration,
}

impl Progress {
    /// Ticks per second of the sim's own CPU time since `earlier`: what the sim does with the
    /// CPU it gets, which time the host's other tenants take from this VM does not change.
    fn per_cpu_s(&self, earlier: &Self) -> f64 {
        (self.tick - earlier.tick) as f64 / (self.cpu - earlier.cpu).as_secs_f64().max(1e-9)
    }

    /// Ticks per wall-clock second since `earlier`.
    fn per_s(&self, earlier: &Self) -> f64 {
        (self.tick - earlier.tick) as f64 / (self.at - earlier.at).as_secs_f64().max(1e-9)
    }
}

/// CPU time (user and system, all threads) process `pid` has used.
fn cpu_time(pid: i32) -> Duration {
    let mut clock: libc::clockid_t = 0;
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: both calls write one value through a valid pointer; `pid` is a live process of
    // the test's own user, whose CPU clock it may read.
    let ok = unsafe {
        libc::clock_getcpuclockid(pid, &raw mut clock) == 0
            && libc::clock_gettime(clock, &raw mut ts) == 0
    };
    assert!(ok, "the CPU clock of process {pid}");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

fn kill9(pid: i32) {
    // SAFETY: kill(2) on a process of the test's own run, found alive a moment ago.
    assert_eq!(
        unsafe { libc::kill(pid, libc::SIGKILL) },
        0,
        "kill -9 {pid}"
    );
}

/// Checkpoint `path` and optimizer digest named by the learner log's last "learner resumes"
/// line.
fn last_resume(log: &Path) -> (PathBuf, String) {
    let text = std::fs::read_to_string(log).expect("learner log");
    let line = text
        .lines()
        .rev()
        .find(|l| l.contains("learner resumes "))
        .unwrap_or_else(|| panic!("no resume line in\n{text}"));
    let rest = &line[line.find("learner resumes ").expect("found") + 16..];
    let path = rest.split(" at version").next().expect("path");
    let digest = rest
        .split("optimizer digest ")
        .nth(1)
        .and_then(|d| d.get(..8))
        .expect("digest");
    (PathBuf::from(path), digest.to_string())
}

fn lavatube(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(args)
        .current_dir(support::root())
        .output()
        .expect("lavatube runs")
}

/// A process built with an older `Transition`: same service, another layout and type name.
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.Transition.v0")]
struct OldTransition {
    obs: [f32; 10],
    reward: f32,
}

#[test]
fn the_sim_survives_learner_and_estimator_faults_swaps_and_strangers() {
    let run = format!("survive-{}", std::process::id());
    let launcher = support::Launched::start(CONFIG, &run);
    let dir = support::root().join("target/e2e-runs").join(&run);
    let learner_log = dir.join("logs/learner.log");
    let mut m = Monitor::connect(&run);
    m.until("two PPO updates", |m| {
        m.policy_log.iter().any(|(v, _)| *v >= 2)
    });
    let start = m.progress();
    m.watch(Duration::from_secs(3));
    let end = m.progress();
    let (before, before_cpu) = (end.per_s(&start), end.per_cpu_s(&start));
    assert!(before > 0.0, "the sim steps");

    // kill -9 of the learner mid-update: right after a rollout chunk arrives it is training.
    let first = m.pid("learner");
    let chunks = m.chunks;
    m.until("a rollout chunk", |m| m.chunks > chunks);
    let killed = m.progress();
    kill9(first);
    let killed_at = killed.at;
    let last_old = *m.versions_of(first).last().expect("versions");
    m.until("the restarted learner's first policy", |m| {
        m.policy_log
            .iter()
            .any(|(_, l)| *l as i32 != first && *l != 0)
    });
    let back = m.progress();
    let back_at = back.at;
    let (during, during_cpu) = (back.per_s(&killed), back.per_cpu_s(&killed));
    let second = m.policy_log.last().expect("policy").1 as i32;
    m.until("an update by the restarted learner", |m| {
        m.versions_of(second).iter().any(|v| *v > last_old)
    });
    let versions = m.versions_of(second);
    assert_eq!(versions[0], last_old, "resumes the last published version");
    assert_eq!(
        versions.iter().find(|v| **v > last_old),
        Some(&(last_old + 1)),
        "its first new version is the last one plus 1: {versions:?}"
    );
    // The sim never waits for a learner: no pause in its ticks, and its rate per CPU second
    // holds (a sim spinning for its learner would keep its CPU and lose ticks). Its rate per
    // wall-clock second also depends on what else the host runs, so it is held to half.
    let pause = m.longest_pause(killed_at, back_at);
    assert!(
        pause < Duration::from_millis(500)
            && during_cpu >= 0.8 * before_cpu
            && during >= 0.5 * before,
        "during the outage vs before: ticks per CPU second {during_cpu:.0} vs \
         {before_cpu:.0}, per second {during:.0} vs {before:.0}; longest pause {pause:?}"
    );
    let (resumed, digest) = last_resume(&learner_log);
    let ckpt = learner_proc::checkpoint::read(&resumed).expect("resumed checkpoint");
    assert_eq!(ckpt.counters.policy_version, last_old);
    assert_eq!(
        format!("{:08x}", ckpt.adam.digest()),
        digest,
        "optimizer moments equal the checkpoint's"
    );
    eprintln!(
        "learner kill -9: ticks/s before {before:.0}, during the {:.1} s outage {during:.0}; \
         per CPU second {before_cpu:.0} and {during_cpu:.0}",
        (back_at - killed_at).as_secs_f64()
    );

    // A truncated newest checkpoint: the next restart names it and falls back.
    let ckpt_dir = dir.join("checkpoints");
    kill9(m.pid("learner"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&ckpt_dir)
        .expect("checkpoints")
        .map(|e| e.expect("entry").path())
        .collect();
    files.sort();
    let newest = files.pop().expect("a checkpoint");
    let bytes = std::fs::read(&newest).expect("read");
    std::fs::write(&newest, &bytes[..bytes.len() / 2]).expect("truncate");
    let third_wait = m.policy_log.len();
    m.until("the learner after the truncated checkpoint", |m| {
        m.policy_log[third_wait..]
            .iter()
            .any(|(_, l)| *l as i32 != second)
    });
    let text = std::fs::read_to_string(&learner_log).expect("log");
    let name = newest.file_name().expect("name").to_string_lossy();
    assert!(
        text.contains(&format!("{name} is corrupt")),
        "the corrupt checkpoint is named:\n{text}"
    );
    assert_eq!(last_resume(&learner_log).0, files.pop().expect("previous"));

    // A swap to a network of the wrong shape is refused; the learner keeps running.
    let tmp = tempfile::tempdir().expect("tempdir");
    let base = std::fs::read_to_string(support::root().join(CONFIG)).expect("config");
    let write = |name: &str, from: &str, to: &str| {
        let p = tmp.path().join(name);
        assert!(base.contains(from));
        std::fs::write(&p, base.replace(from, to)).expect("write config");
        p.display().to_string()
    };
    let wide = write(
        "wide.toml",
        "anneal-lr = false",
        "anneal-lr = false\nhidden = [16, 16]",
    );
    let learner = m.pid("learner");
    let out = lavatube(&["swap-learner", "--run-id", &run, "--config", &wide]);
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("ppo.hidden") && said.contains("swap refused"),
        "{said}"
    );
    assert_eq!(m.pid("learner"), learner);

    // A graceful swap to another learning rate while the sim steps on.
    let slow = write("slow.toml", "learning-rate = 3e-4", "learning-rate = 1e-4");
    let swap_from = Instant::now();
    let mut swap = Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(["swap-learner", "--run-id", &run, "--config", &slow])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("swap-learner");
    let swapped = loop {
        m.watch(Duration::from_millis(50));
        if let Some(status) = swap.try_wait().expect("poll") {
            break status;
        }
    };
    let swap_to = Instant::now();
    assert!(swapped.success());
    // The swap returns once the new learner is started; its node comes up a moment later.
    m.until("the swapped-in learner's node", |m| {
        m.live_pid("learner").is_some_and(|p| p != learner)
    });
    let swapped_in = m.pid("learner");
    assert_ne!(swapped_in, learner);
    let in_swap = m.rate(swap_from, swap_to);
    let resumed_at = m.versions_of(swapped_in).first().copied();
    m.until("an update by the swapped-in learner", |m| {
        m.versions_of(swapped_in)
            .iter()
            .any(|v| Some(*v) > resumed_at)
    });
    let t1 = Instant::now();
    m.watch(Duration::from_secs(2));
    let after = m.rate(t1, Instant::now());
    eprintln!(
        "swap: ticks/s before {before:.0}, during the {:.1} s swap {in_swap:.0}, after {after:.0}",
        (swap_to - swap_from).as_secs_f64()
    );
    // Two learners start during a swap (the check, then the new one): on 2 cores the sim
    // slows down but never stops.
    assert!(in_swap > 0.0, "the sim never stops");
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).expect("metrics");
    let mut rows = csv::Reader::from_reader(metrics.as_bytes());
    let lr_col = rows
        .headers()
        .expect("header")
        .iter()
        .position(|h| h == "learning_rate")
        .expect("learning_rate column");
    let last_lr: f64 = rows.records().last().expect("rows").expect("row")[lr_col]
        .parse()
        .expect("number");
    assert!(
        (last_lr - 1e-4).abs() < 1e-9,
        "the new rate shows: {last_lr}"
    );
    assert!(
        ipc::list_nodes(&run)
            .expect("nodes")
            .iter()
            .all(|n| n.pid != learner),
        "nothing of the old learner remains"
    );

    // kill -9 of the estimator: the sim steps on and the launcher restarts it.
    let estimator = m.pid("estimator");
    kill9(estimator);
    let tick = m.last_tick();
    m.until("a restarted estimator", |m| {
        ipc::list_nodes(&m.run)
            .expect("nodes")
            .iter()
            .any(|n| n.alive && n.name == "estimator" && n.pid != estimator)
    });
    assert!(m.last_tick() > tick, "the sim stepped meanwhile");

    // A process with another wire version is refused at connect; the run goes on.
    let stranger: ipc::Channel<OldTransition, RolloutHeader> =
        ipc::Channel::new(ipc::ROLLOUT.service, ipc::ROLLOUT.capacity);
    let err = m.bus.receiver(&stranger, None).err().expect("refused");
    assert!(
        err.to_string()
            .contains("different version of its message types"),
        "{err}"
    );
    let tick = m.last_tick();
    m.watch(Duration::from_secs(1));
    assert!(m.last_tick() > tick, "the others keep running");

    drop(m);
    // SAFETY: SIGINT to the launcher we started: it stops its run like Ctrl-C.
    unsafe {
        libc::kill(launcher.child.id() as i32, libc::SIGINT);
    }
    let (code, output) = launcher.wait();
    assert_eq!(code, 130, "{output}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).expect("summary"))
            .expect("json");
    assert_eq!(summary["restarts"]["learner"], 2, "{summary}");
    assert_eq!(summary["restarts"]["estimator"], 1, "{summary}");
    assert_eq!(summary["learner_swaps"], 1, "{summary}");
    assert!(
        ipc::run_files(&run).is_empty(),
        "{:?}",
        ipc::run_files(&run)
    );
}
