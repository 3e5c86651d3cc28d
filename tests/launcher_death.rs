//! DESIGN §4 when the launcher itself dies: `kill -9` of `lavatube run` leaves nothing
//! running. Each child asked the kernel for SIGTERM on its launcher's death, so the sim and
//! the estimator stop and the learner checkpoints and stops; `lavatube clean` then removes
//! the run's shared memory, and `lavatube run --resume` goes on from the checkpoint.

use common::ipc;
use common::run_dir;
use common::wire::{PolicyHeader, TickHeader};
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/survival.toml";
/// Long enough for a debug-build learner to start and do an update.
const PATIENCE: Duration = Duration::from_secs(120);

/// Waits for a telemetry tick and a policy of at least `version`; the first tick seen
/// and the first policy header seen.
fn until_going(watch: &support::Watch, version: u32) -> (TickHeader, PolicyHeader) {
    let give_up = Instant::now() + PATIENCE;
    let (mut tick, mut first, mut newest) = (None, None, 0);
    while newest < version || tick.is_none() {
        assert!(Instant::now() < give_up, "the run did not get going");
        watch.ticks.wait(Duration::from_millis(10)).expect("wait");
        if let Some(t) = watch.ticks.try_recv().expect("telemetry") {
            tick.get_or_insert(*t.user_header());
        }
        while let Some(p) = watch.policies.try_recv().expect("policy") {
            let h = *p.user_header();
            first.get_or_insert(h);
            newest = newest.max(h.version);
        }
    }
    (tick.expect("a tick"), first.expect("a policy"))
}

/// The newest checkpoint's update number in `dir`.
fn newest_checkpoint(dir: &std::path::Path) -> u64 {
    std::fs::read_dir(dir.join(run_dir::CHECKPOINTS))
        .expect("checkpoints")
        .filter_map(|e| run_dir::parse_checkpoint_file(&e.ok()?.file_name().to_string_lossy()))
        .max()
        .expect("a checkpoint")
}

#[test]
fn a_killed_launcher_leaves_nothing_behind_and_its_run_resumes_from_the_checkpoint() {
    let run = format!("orphan-{}", std::process::id());
    let launcher = support::Launched::start(CONFIG, &run);
    let dir = support::root().join("target/e2e-runs").join(&run);
    let monitor = support::Watch::connect(&run, "monitor");
    until_going(&monitor, 1);
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
    support::until_gone(&children, killed, PATIENCE);
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
    drop(monitor);

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

    // The run goes on from its checkpoint: the learner's update count, policy versions and
    // the sim's step count continue; nothing starts over.
    let saved = newest_checkpoint(&dir);
    let dir_arg = dir.display().to_string();
    let resumed = support::Launched::run(&["--resume", &dir_arg], &format!("{run}-resumed"));
    let monitor = support::Watch::connect(&run, "monitor");
    let (tick, policy) = until_going(&monitor, saved as u32 + 1);
    assert!(
        u64::from(policy.version) >= saved,
        "the resumed learner publishes version {} after {saved} updates",
        policy.version
    );
    assert!(
        tick.env_steps > policy.env_steps && policy.env_steps >= saved * 1024,
        "the sim counts on from the checkpoint's {} steps: first tick at {}",
        policy.env_steps,
        tick.env_steps
    );
    drop(monitor);
    let (code, said) = resumed.wait_interrupted();
    assert_eq!(code, 130, "{said}");
    assert!(said.contains("(resumed)"), "{said}");
    let updates = support::update_numbers(&dir);
    assert!(
        updates.windows(2).all(|w| w[1] > w[0]) && updates.contains(&(saved + 1)),
        "one update sequence across the resume: {updates:?}"
    );
}
