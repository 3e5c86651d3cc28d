//! DESIGN §4 when the launcher itself dies: `kill -9` of `lavatube run` leaves nothing
//! running. Each child asked the kernel for SIGTERM on its launcher's death, so the sim and
//! the estimator stop and the learner checkpoints and stops; `lavatube clean` then removes
//! the run's shared memory.

use common::ipc::{self, Bus};
use common::wire::{EnvTick, PolicyHeader, TickHeader};
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/survival.toml";
/// Long enough for a debug-build learner to start and do an update.
const PATIENCE: Duration = Duration::from_secs(120);

/// Whether `pid` still runs. A zombie (exited, not yet reaped by whoever adopted it) counts
/// as gone: it holds no memory, no shared-memory port, no CPU.
fn running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| {
        let state = s.rsplit(") ").next().and_then(|rest| rest.chars().next());
        !matches!(state, Some('Z' | 'X') | None)
    })
}

#[test]
fn a_killed_launcher_leaves_no_process_and_clean_leaves_no_shared_memory() {
    let run = format!("orphan-{}", std::process::id());
    let launcher = support::Launched::start(CONFIG, &run);
    let dir = support::root().join("target/e2e-runs").join(&run);
    let bus = Bus::connect(&run, "monitor").expect("monitor node");
    let ticks = bus
        .receiver::<EnvTick, TickHeader>(&ipc::TELEMETRY, None)
        .expect("telemetry");
    let policies = bus
        .receiver::<f32, PolicyHeader>(&ipc::POLICY, Some("general"))
        .expect("policy");
    let give_up = Instant::now() + PATIENCE;
    let (mut version, mut ticked) = (0, false);
    while version < 1 || !ticked {
        assert!(Instant::now() < give_up, "the run did not get going");
        ticks.wait(Duration::from_millis(10)).expect("wait");
        ticked |= ticks.try_recv().expect("telemetry").is_some();
        while let Some(p) = policies.try_recv().expect("policy") {
            version = version.max(p.user_header().version);
        }
    }
    let children: Vec<(String, i32)> = ipc::list_nodes(&run)
        .expect("nodes")
        .into_iter()
        .filter(|n| n.alive && n.name != "launcher" && n.name != "monitor")
        .map(|n| (n.name, n.pid))
        .collect();
    let names: Vec<&str> = children.iter().map(|(n, _)| n.as_str()).collect();
    for role in ["learner", "estimator", "sim"] {
        assert!(names.contains(&role), "{role} runs: {names:?}");
    }

    // SAFETY: kill(2) on the launcher this test started; the guard reaps it.
    assert_eq!(
        unsafe { libc::kill(launcher.child.id() as i32, libc::SIGKILL) },
        0
    );
    let (killed, killed_at) = (Instant::now(), std::time::SystemTime::now());
    let mut left = children.clone();
    while !left.is_empty() {
        assert!(
            killed.elapsed() < PATIENCE,
            "still running {:?} after the launcher died",
            left
        );
        left.retain(|(_, pid)| running(*pid));
        std::thread::sleep(Duration::from_millis(10));
    }
    eprintln!(
        "every child of the killed launcher stopped within {:.2} s",
        killed.elapsed().as_secs_f64()
    );
    let newest = std::fs::read_dir(dir.join("checkpoints"))
        .expect("checkpoints")
        .filter_map(|e| e.ok()?.metadata().ok()?.modified().ok())
        .max()
        .expect("a checkpoint");
    assert!(
        newest >= killed_at,
        "the learner checkpointed on its way out"
    );
    let log = std::fs::read_to_string(dir.join("logs/learner.log")).expect("learner log");
    assert!(
        log.lines().any(|l| l.contains("learner done")),
        "the learner's log is whole, to its last line:\n{log}"
    );
    drop((ticks, policies, bus));

    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(["clean", "--run-id", &run])
        .output()
        .expect("lavatube clean");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(ipc::run_files(&run), Vec::<std::path::PathBuf>::new());
    drop(launcher);
}
