//! The churn soak (ignored; `scripts/soak.sh` runs it for 30 minutes): an async run on
//! tests/fixtures/survival.toml in which, with `LAVATUBE_SOAK_FAULTS=1`, the learner or the
//! estimator is killed with SIGKILL every 20–60 s and the learner is swapped every 3 minutes.
//! With `LAVATUBE_SOAK_FAULTS=0` the same run goes undisturbed, for comparison. It reports
//! restarts, swaps, the policy versions seen, chunks missed, the sim's ticks/s and every
//! process's RSS over time, files left in shared memory and the success rate, and checks
//! that versions only grow with none skipped, nothing is left in shared memory, and neither
//! the tick rate nor any process's memory drifts.

use common::ipc;
use common::run_dir;
use common::wire::TickHeader;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/survival.toml";
/// How often ticks/s and RSS are sampled.
const SAMPLE_EVERY: Duration = Duration::from_secs(15);
const SWAP_EVERY: Duration = Duration::from_secs(180);

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Resident set size of `pid`, MiB, from /proc.
fn rss_mib(pid: i32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: f64 = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// A small deterministic stream for the fault schedule.
struct Lcg(u64);

impl Lcg {
    fn next_in(&mut self, lo: u64, hi: u64) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        lo + (self.0 >> 33) % (hi - lo + 1)
    }
}

#[test]
#[ignore = "a soak of minutes to hours: scripts/soak.sh"]
fn churn_soak() {
    let secs = env_or("LAVATUBE_SOAK_SECS", 120);
    let faults = env_or("LAVATUBE_SOAK_FAULTS", 1) != 0;
    let run = format!(
        "soak-{}-{}",
        if faults { "faults" } else { "quiet" },
        std::process::id()
    );
    let launcher = support::Launched::start(CONFIG, &run);
    let dir = support::root().join("target/e2e-runs").join(&run);
    let watch = support::Watch::connect(&run, "monitor");
    let (ticks, policies) = (&watch.ticks, &watch.policies);

    let started = Instant::now();
    let mut rng = Lcg(u64::from(std::process::id()));
    let mut next_kill = started + Duration::from_secs(rng.next_in(20, 60));
    let mut next_swap = started + SWAP_EVERY;
    let mut next_sample = started + SAMPLE_EVERY;
    let (mut kills, mut swaps_ok) = (BTreeMap::<&str, u32>::new(), 0u32);
    let mut versions: Vec<u32> = Vec::new();
    let mut last = TickHeader::default();
    let mut at_sample = (started, 0u64, 0u64, 0u64);
    let mut samples: Vec<serde_json::Value> = Vec::new();
    let mut swap: Option<std::process::Child> = None;
    while started.elapsed() < Duration::from_secs(secs) {
        ticks.wait(Duration::from_millis(20)).expect("wait");
        while let Some(t) = ticks.try_recv().expect("telemetry") {
            last = *t.user_header();
        }
        while let Some(p) = policies.try_recv().expect("policy") {
            versions.push(p.user_header().version);
        }
        let now = Instant::now();
        if now >= next_sample {
            let (t0, tick0, ep0, ok0) = at_sample;
            let window = now.duration_since(t0).as_secs_f64();
            let nodes = ipc::list_nodes(&run).unwrap_or_default();
            let rss: BTreeMap<String, Option<f64>> = nodes
                .iter()
                .filter(|n| n.alive)
                .map(|n| (n.name.clone(), rss_mib(n.pid)))
                .chain([("launcher".to_string(), rss_mib(launcher.child.id() as i32))])
                .collect();
            let episodes = last.episodes - ep0;
            samples.push(serde_json::json!({
                "t_s": started.elapsed().as_secs(),
                "ticks_per_s": (last.tick - tick0) as f64 / window,
                "success_rate": (episodes > 0).then(|| (last.successes - ok0) as f64 / episodes as f64),
                "policy_version": last.policy_version,
                "rss_mib": rss,
            }));
            at_sample = (now, last.tick, last.episodes, last.successes);
            next_sample = now + SAMPLE_EVERY;
        }
        if faults && now >= next_kill {
            let victim = if rng.next_in(0, 1) == 0 {
                "learner"
            } else {
                "estimator"
            };
            if let Some(n) = ipc::list_nodes(&run)
                .unwrap_or_default()
                .into_iter()
                .find(|n| n.alive && n.name == victim)
            {
                // SAFETY: kill(2) on a process of the soak's own run, alive a moment ago.
                unsafe {
                    libc::kill(n.pid, libc::SIGKILL);
                }
                *kills.entry(victim).or_default() += 1;
            }
            next_kill = now + Duration::from_secs(rng.next_in(20, 60));
        }
        // A swap takes seconds: it runs beside the loop, which keeps draining the monitor's
        // small policy buffer meanwhile (a blocked reader would miss versions).
        if let Some(s) = swap.as_mut()
            && let Some(status) = s.try_wait().expect("swap-learner")
        {
            swaps_ok += u32::from(status.success());
            swap = None;
        }
        if faults && now >= next_swap && swap.is_none() {
            swap = Some(
                std::process::Command::new(env!("CARGO_BIN_EXE_lavatube"))
                    .args(["swap-learner", "--run-id", &run])
                    .current_dir(support::root())
                    .stdout(std::process::Stdio::null())
                    .stderr(std::process::Stdio::null())
                    .spawn()
                    .expect("swap-learner runs"),
            );
            next_swap = now + SWAP_EVERY;
        }
    }
    if let Some(mut s) = swap {
        swaps_ok += u32::from(s.wait().expect("swap-learner").success());
    }
    drop(watch);
    let (code, said) = launcher.wait_interrupted();
    let left = ipc::run_files(&run);
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(run_dir::SUMMARY_JSON)).expect("summary"),
    )
    .expect("summary json");
    let learner_log =
        std::fs::read_to_string(run_dir::log_file(&dir, "learner")).expect("learner log");
    let missed: u64 = learner_log
        .lines()
        .filter(|l| l.contains("learner done"))
        .filter_map(|l| {
            l.split("chunks_missed=")
                .nth(1)?
                .split(' ')
                .next()?
                .parse::<u64>()
                .ok()
        })
        .sum();
    let mut distinct = versions.clone();
    distinct.dedup();
    let monotone = versions.windows(2).all(|w| w[1] >= w[0]);
    let gap_free = distinct.windows(2).all(|w| w[1] == w[0] + 1);
    // The learner's own record: one metrics row per update, across every restart and swap.
    let mut metrics = csv::Reader::from_path(dir.join(run_dir::METRICS_CSV)).expect("metrics.csv");
    let col = metrics
        .headers()
        .expect("header")
        .iter()
        .position(|h| h == "policy_version")
        .expect("a policy_version column");
    let updates: Vec<u32> = metrics
        .records()
        .map(|r| r.expect("a row")[col].parse().expect("a version"))
        .collect();
    let updates_gap_free = updates.windows(2).all(|w| w[1] == w[0] + 1);
    let report = serde_json::json!({
        "run": run,
        "seconds": secs,
        "faults": faults,
        "kills": kills,
        "swaps_accepted": swaps_ok,
        "restarts": summary["restarts"],
        "learner_swaps": summary["learner_swaps"],
        "policy_versions": { "first": distinct.first(), "last": distinct.last(), "distinct": distinct.len(), "monotone": monotone, "gap_free": gap_free },
        "metrics_versions": { "first": updates.first(), "last": updates.last(), "rows": updates.len(), "gap_free": updates_gap_free },
        "chunks_missed": missed,
        "files_left_in_shared_memory": left.len(),
        "success_rate": summary["success_rate"],
        "env_steps": summary["env_steps"],
        "samples": samples,
    });
    let text = serde_json::to_string_pretty(&report).expect("report");
    eprintln!("{text}");
    if let Ok(path) = std::env::var("LAVATUBE_SOAK_REPORT") {
        std::fs::write(&path, &text).expect("report file");
    }
    assert_eq!(code, 130, "the run was still going at the end: {said}");
    assert!(monotone && gap_free, "policy versions: {distinct:?}");
    assert!(updates_gap_free, "versions in metrics.csv: {updates:?}");
    assert!(left.is_empty(), "left in shared memory: {left:?}");
}
