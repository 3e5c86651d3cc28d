//! Runs across hosts (DESIGN §9), each host its own launcher with its own run id and shared
//! memory, their bridges meeting over Zenoh: two sim hosts feed one learner host on loopback,
//! and a sim host in one network namespace feeds a learner host in another, across a veth
//! pair, so nothing but TCP can carry what the bridge carries. A sim host that dies is
//! reported gone and counts again when it rejoins; a killed learner on the learner host
//! resumes from its checkpoint while the sims step on.

use common::Config;
use common::config::PolicySlot;
use common::run_dir;
use learner_proc::Learner;
use std::path::PathBuf;
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/hosts.toml";

/// The learner host's run directory, its learner's log and its last checkpoint.
fn learned(run: &str) -> (String, Learner) {
    let root = support::root();
    let dir: PathBuf = root.join("target/e2e-runs").join(run);
    let cfg = Config::load(&root.join(CONFIG)).expect("config");
    let log = std::fs::read_to_string(run_dir::log_file(&dir, "learner")).expect("learner log");
    let ckpt = run_dir::learner_dir(&dir, PolicySlot::General).join(run_dir::CHECKPOINTS);
    let (learner, _) = Learner::resume(&cfg, &ckpt).expect("the learner host's checkpoint");
    (log, learner)
}

#[test]
fn two_sim_hosts_feed_one_learner_host_and_every_chunk_is_trained_on() {
    let pid = std::process::id();
    let hosts = support::AcrossHosts::new(CONFIG, &format!("two-{pid}"), 2);
    let learner_run = format!("two-l-{pid}");
    let learner = hosts.learner_host(&learner_run);
    let sims = [1, 2].map(|source| hosts.sim_host(&format!("two-s{source}-{pid}"), source));
    for (source, sim) in sims.into_iter().enumerate() {
        let (code, said) = sim.wait();
        assert_eq!(code, 0, "sim host {} failed:\n{said}", source + 1);
    }
    let (code, said) = learner.wait();
    assert_eq!(code, 0, "the learner host failed:\n{said}");
    let (log, learner) = learned(&learner_run);
    // 8192 steps per host in chunks of 1024 transitions: 8 chunks each, none missed.
    assert!(
        log.contains("source 1: 8 chunks (0 missed), source 2: 8 chunks (0 missed)"),
        "{log}"
    );
    assert_eq!(
        learner.counters().global_step,
        2 * 8192,
        "both hosts' steps add up"
    );
    let metrics = support::root()
        .join("target/e2e-runs")
        .join(&learner_run)
        .join(run_dir::METRICS_CSV);
    let metrics = std::fs::read_to_string(metrics).expect("metrics.csv");
    assert!(
        metrics
            .lines()
            .last()
            .is_some_and(|l| l.ends_with(",1:8 2:8")),
        "per-source chunk counts in the last metrics row:\n{metrics}"
    );
    assert_eq!(
        learner.counters().update,
        16,
        "one update per chunk of either host"
    );
}

/// Runs `ip ARGS…`, failing the test with its error.
fn ip(args: &[&str]) {
    let out = std::process::Command::new("ip")
        .args(args)
        .output()
        .expect("ip runs");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Two network namespaces joined by a veth pair, 10.77.x.1 and .2, removed on drop.
struct Namespaces {
    names: [String; 2],
}

impl Namespaces {
    fn new(tag: u32) -> Self {
        let names = [format!("lt-a-{tag}"), format!("lt-b-{tag}")];
        let net = tag % 250;
        for n in &names {
            ip(&["netns", "add", n]);
            ip(&["-n", n, "link", "set", "lo", "up"]);
        }
        let (va, vb) = (format!("lta{net}"), format!("ltb{net}"));
        ip(&[
            "link", "add", &va, "netns", &names[0], "type", "veth", "peer", "name", &vb, "netns",
            &names[1],
        ]);
        for (n, dev, host) in [(&names[0], &va, 1), (&names[1], &vb, 2)] {
            ip(&[
                "-n",
                n,
                "addr",
                "add",
                &format!("10.77.{net}.{host}/24"),
                "dev",
                dev,
            ]);
            ip(&["-n", n, "link", "set", dev, "up"]);
        }
        Self { names }
    }
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        for n in &self.names {
            let _ = std::process::Command::new("ip")
                .args(["netns", "del", n])
                .status();
        }
    }
}

#[test]
fn a_sim_host_in_another_network_namespace_feeds_the_learner_over_a_veth_pair() {
    // SAFETY: geteuid(2) has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("skipped: network namespaces need root");
        return;
    }
    let pid = std::process::id();
    let ns = Namespaces::new(pid);
    let net = pid % 250;
    let hosts = support::AcrossHosts::new(CONFIG, &format!("veth-{pid}"), 1);
    let port = hosts.endpoint.rsplit(':').next().expect("port").to_string();
    let (listen, connect) = (
        format!("tcp/10.77.{net}.1:{port}"),
        format!("tcp/10.77.{net}.1:{port}"),
    );
    let learner_run = format!("veth-l-{pid}");
    let learner = support::Launched::command(
        &["ip", "netns", "exec", &ns.names[0], "run"],
        &[
            "--config",
            &hosts.config,
            "--run-id",
            &learner_run,
            "--listen",
            &listen,
        ],
        &learner_run,
    );
    let sim_run = format!("veth-s-{pid}");
    let sim = support::Launched::command(
        &["ip", "netns", "exec", &ns.names[1], "join"],
        &[
            "--config",
            &hosts.config,
            "--run-id",
            &sim_run,
            "--connect",
            &connect,
            "--source",
            "1",
        ],
        &sim_run,
    );
    let (code, said) = sim.wait();
    assert_eq!(code, 0, "the sim host failed:\n{said}");
    let (code, said) = learner.wait();
    assert_eq!(code, 0, "the learner host failed:\n{said}");
    let (log, learner) = learned(&learner_run);
    assert!(log.contains("source 1: 8 chunks (0 missed)"), "{log}");
    assert_eq!(learner.counters().global_step, 8192);
}

/// The value of `name=` in a log line.
fn field<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(name)?.strip_prefix('='))
}

/// Waits up to `limit` for `done`, which sees the learner host's bridge log each time.
fn until_bridge_says(
    log: &std::path::Path,
    limit: Duration,
    what: &str,
    done: impl Fn(&str) -> bool,
) {
    let started = Instant::now();
    loop {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        if done(&text) {
            return;
        }
        assert!(
            started.elapsed() < limit,
            "{what}: not within {limit:?}:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Reports of chunks from `source` after the `nth` time it joined (0-based).
fn chunks_after_join(log: &str, source: u32, nth: usize) -> u64 {
    let joined = format!("source=Some({source})");
    let from = log
        .match_indices("sim host joined")
        .filter(|(i, _)| {
            log[*i..]
                .lines()
                .next()
                .is_some_and(|l| l.contains(&joined))
        })
        .nth(nth)
        .map_or(log.len(), |(i, _)| i);
    log[from..]
        .lines()
        .filter(|l| l.contains("rollouts from sim host"))
        .filter(|l| field(l, "source") == Some(&source.to_string()))
        .filter_map(|l| field(l, "chunks")?.parse::<u64>().ok())
        .sum()
}

/// The newest general policy version the watch has seen, draining it.
fn newest_version(w: &support::Watch, last: &mut Vec<u32>) -> Option<u32> {
    while let Some(p) = w.policies.try_recv().expect("policy") {
        last.push(p.user_header().version);
    }
    last.last().copied()
}

/// Keeps draining the watch's policies into `seen` for `d` (its buffer holds 2).
fn watch_for(w: &support::Watch, seen: &mut Vec<u32>, d: Duration) {
    let end = Instant::now() + d;
    while Instant::now() < end {
        newest_version(w, seen);
        w.policies.wait(Duration::from_millis(20)).expect("wait");
    }
}

/// Waits until `lavatube status` lists every line of `want` for run `run` (the bridge
/// publishes its table every second).
fn until_status(run: &str, want: &[&str]) {
    let started = Instant::now();
    loop {
        let said = support::status_of(run);
        if want.iter().all(|w| said.contains(w)) {
            return;
        }
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "{want:?} not in lavatube status:\n{said}"
        );
        std::thread::sleep(Duration::from_millis(300));
    }
}

/// SIGKILL to `pids`.
fn kill_all(pids: &[i32]) {
    for &pid in pids {
        // SAFETY: kill(2) on processes of this test's own runs, alive a moment ago.
        unsafe {
            libc::kill(pid, libc::SIGKILL);
        }
    }
}

#[test]
fn a_dead_sim_host_is_reported_gone_rejoins_and_a_killed_learner_resumes_while_sims_step() {
    let pid = std::process::id();
    let hosts =
        support::AcrossHosts::new("tests/fixtures/survival.toml", &format!("churn-{pid}"), 2);
    let learner_run = format!("churn-l-{pid}");
    let learner_host = hosts.learner_host(&learner_run);
    let sim1_run = format!("churn-s1-{pid}");
    let _sim1 = hosts.sim_host(&sim1_run, 1);
    let sim2_run = format!("churn-s2-{pid}");
    let sim2 = hosts.sim_host(&sim2_run, 2);
    let log = run_dir::log_file(
        &support::root().join("target/e2e-runs").join(&learner_run),
        "bridge",
    );
    let learner = support::Watch::connect(&learner_run, "monitor");
    let sim1 = support::Watch::connect(&sim1_run, "monitor");
    let minute = Duration::from_secs(60);

    until_bridge_says(&log, minute, "both sim hosts' chunks arrive", |t| {
        chunks_after_join(t, 1, 0) > 0 && chunks_after_join(t, 2, 0) > 0
    });
    until_status(
        &learner_run,
        &["source 1     joined", "source 2     joined"],
    );

    // A sim host dies whole: its launcher and every process of its run, at once.
    let mut doomed: Vec<i32> = common::ipc::list_nodes(&sim2_run)
        .expect("nodes")
        .iter()
        .filter(|n| n.alive && n.name != "monitor")
        .map(|n| n.pid)
        .collect();
    doomed.push(sim2.child.id() as i32);
    kill_all(&doomed);
    until_bridge_says(&log, minute, "sim host 2 reported gone", |t| {
        t.lines()
            .any(|l| l.contains("sim host gone") && l.contains("source=Some(2)"))
    });
    until_status(&learner_run, &["source 1     joined", "source 2     gone"]);
    let mut seen = Vec::new();
    let before = newest_version(&learner, &mut seen).unwrap_or(0);
    let started = Instant::now();
    while newest_version(&learner, &mut seen).unwrap_or(0) < before + 3 {
        assert!(
            started.elapsed() < minute,
            "the learner stopped updating: {seen:?}"
        );
        learner
            .policies
            .wait(Duration::from_millis(50))
            .expect("wait");
    }

    // It comes back, under a new run id on its host, with its source id.
    let _sim2 = hosts.sim_host(&format!("churn-s2b-{pid}"), 2);
    until_bridge_says(&log, minute, "sim host 2's chunks count again", |t| {
        chunks_after_join(t, 2, 1) > 0
    });

    // The learner host's learner is killed: the sims step on, and training resumes with the
    // next version.
    let ticks = |w: &support::Watch| {
        let mut last = None;
        while let Some(t) = w.ticks.try_recv().expect("telemetry") {
            last = Some(t.user_header().tick);
        }
        last
    };
    let learner_pid = common::ipc::list_nodes(&learner_run)
        .expect("nodes")
        .into_iter()
        .find(|n| n.alive && n.name == "learner")
        .expect("the learner")
        .pid;
    // The versions seen from here on must go on without a gap.
    seen.clear();
    let at = |w: &support::Watch| (Instant::now(), ticks(w).expect("sim host 1 steps"));
    let start = at(&sim1);
    watch_for(&learner, &mut seen, Duration::from_millis(1500));
    let last_before = *seen.last().expect("a version while training");
    let before_kill = at(&sim1);
    kill_all(&[learner_pid]);
    watch_for(&learner, &mut seen, Duration::from_millis(1500));
    let in_outage = at(&sim1);
    assert!(in_outage.1 > before_kill.1, "the sims stepped on");
    let rate = |(t0, k0): (Instant, u64), (t1, k1): (Instant, u64)| {
        (k1 - k0) as f64 / t1.duration_since(t0).as_secs_f64()
    };
    // Measured, not asserted (a timing): the closing report quotes it.
    eprintln!(
        "sim host 1: {:.0} ticks/s before the learner was killed, {:.0} while it was down",
        rate(start, before_kill),
        rate(before_kill, in_outage)
    );
    let started = Instant::now();
    let resumed = loop {
        let newest = newest_version(&learner, &mut seen).unwrap_or(0);
        if newest > last_before {
            break newest;
        }
        assert!(
            started.elapsed() < minute,
            "training did not resume: {seen:?}"
        );
        learner
            .policies
            .wait(Duration::from_millis(50))
            .expect("wait");
    };
    let mut distinct = seen.clone();
    distinct.dedup();
    assert!(
        distinct.windows(2).all(|w| w[1] >= w[0]),
        "versions only grow: {distinct:?}"
    );
    assert!(
        distinct.windows(2).all(|w| w[1] <= w[0] + 1),
        "no version lost across the restart (resumed at {resumed}): {distinct:?}"
    );
    drop((learner, sim1));
    let (code, said) = learner_host.wait_interrupted();
    assert_eq!(code, 130, "{said}");
}

/// One sync run of a learner host and two sim hosts on smoke.toml; the learner's last
/// checkpoint and its log.
fn sync_run_across_two_hosts(tag: &str) -> (Learner, String) {
    let hosts = support::AcrossHosts::new("configs/smoke.toml", tag, 2);
    let learner_run = format!("{tag}-l");
    let learner = hosts.learner_host(&learner_run);
    // Source 2 starts first: the round's order must not depend on who comes first.
    let sims = [2, 1].map(|source| hosts.sim_host(&format!("{tag}-s{source}"), source));
    for sim in sims {
        let (code, said) = sim.wait();
        assert_eq!(code, 0, "a sim host failed:\n{said}");
    }
    let (code, said) = learner.wait();
    assert_eq!(code, 0, "the learner host failed:\n{said}");
    let root = support::root();
    let dir = root.join("target/e2e-runs").join(&learner_run);
    let cfg = Config::load(&root.join("configs/smoke.toml")).expect("config");
    let (learner, _) = Learner::resume(&cfg, &dir.join(run_dir::CHECKPOINTS)).expect("checkpoint");
    let log = std::fs::read_to_string(run_dir::log_file(&dir, "learner")).expect("learner log");
    (learner, log)
}

#[test]
fn sync_across_two_sim_hosts_is_one_update_per_round_and_reproducible_from_the_seed() {
    let pid = std::process::id();
    let (a, log) = sync_run_across_two_hosts(&format!("round-a-{pid}"));
    assert!(
        log.contains("source 1: 3 chunks (0 missed), source 2: 3 chunks (0 missed)"),
        "{log}"
    );
    // smoke.toml: 3072 steps per host in chunks of 1024; a round is one chunk of each.
    assert_eq!(a.counters().update, 3, "one update per round");
    assert_eq!(a.counters().global_step, 2 * 3072);
    let (b, _) = sync_run_across_two_hosts(&format!("round-b-{pid}"));
    assert_eq!(a.counters(), b.counters());
    let (wa, wb) = (a.policy_weights(), b.policy_weights());
    assert!(
        wa.iter().zip(&wb).all(|(x, y)| x.to_bits() == y.to_bits()),
        "the same seed gave other weights"
    );
}

#[test]
fn a_learner_host_killed_and_resumed_trains_on_and_its_sim_host_reconnects() {
    let pid = std::process::id();
    let hosts =
        support::AcrossHosts::new("tests/fixtures/survival.toml", &format!("back-{pid}"), 1);
    let learner_run = format!("back-l-{pid}");
    let mut learner_host = hosts.learner_host(&learner_run);
    let sim_run = format!("back-s-{pid}");
    let _sim = hosts.sim_host(&sim_run, 1);
    let sim = support::Watch::connect(&sim_run, "monitor");
    let minute = Duration::from_secs(60);
    let mut seen = Vec::new();
    let started = Instant::now();
    while newest_version(&sim, &mut seen).unwrap_or(0) < 3 {
        assert!(
            started.elapsed() < minute,
            "no training through the bridge: {seen:?}"
        );
        sim.policies.wait(Duration::from_millis(50)).expect("wait");
    }

    // The whole learner host goes: its launcher with SIGKILL, its children after it.
    kill_all(&[learner_host.child.id() as i32]);
    learner_host.child.wait().expect("reaped");
    let until_gone = Instant::now();
    while common::ipc::list_nodes(&learner_run)
        .unwrap_or_default()
        .iter()
        .any(|n| n.alive)
    {
        assert!(
            until_gone.elapsed() < minute,
            "the learner host's children outlived it"
        );
        watch_for(&sim, &mut seen, Duration::from_millis(100));
    }
    let tick = |w: &support::Watch| {
        let mut last = 0;
        while let Some(t) = w.ticks.try_recv().expect("telemetry") {
            last = t.user_header().tick;
        }
        last
    };
    let before = tick(&sim);
    watch_for(&sim, &mut seen, Duration::from_secs(1));
    assert!(
        tick(&sim) > before,
        "the sim host steps on while the learner host is away"
    );
    let last_before = *seen.last().expect("versions");

    let dir = support::root().join("target/e2e-runs").join(&learner_run);
    let dir_arg = dir.display().to_string();
    let resumed = support::Launched::run(
        &["--resume", &dir_arg, "--listen", &hosts.endpoint],
        &format!("{learner_run}-resumed"),
    );
    let started = Instant::now();
    while newest_version(&sim, &mut seen).unwrap_or(0) <= last_before {
        assert!(
            started.elapsed() < minute,
            "the sim host got no newer policy: {seen:?}"
        );
        sim.policies.wait(Duration::from_millis(50)).expect("wait");
    }
    // Measured, not asserted (a timing): the closing report quotes it.
    eprintln!(
        "the sim host acted on a newer policy {:.2} s after `run --resume` started",
        started.elapsed().as_secs_f64()
    );
    let mut distinct = seen.clone();
    distinct.dedup();
    assert!(
        distinct.windows(2).all(|w| w[1] >= w[0]),
        "versions only grow: {distinct:?}"
    );
    drop(sim);
    let (code, said) = resumed.wait_interrupted();
    assert_eq!(code, 130, "{said}");
}
