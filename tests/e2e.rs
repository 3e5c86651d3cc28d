//! End to end: `lavatube run` on configs/smoke.toml as a real process tree — three OS
//! processes talking only through iceoryx2 — checked from the outside.

mod support;

#[test]
fn smoke_run_trains_through_shared_memory_and_cleans_up() {
    let run_id = format!("e2e-{}", std::process::id());
    let (code, output) = support::lavatube_run("configs/smoke.toml", &run_id);
    assert_eq!(code, 0, "launcher output:\n{output}");
    let dir = support::root().join("target/e2e-runs").join(&run_id);
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("summary.json")).expect("summary.json"),
    )
    .expect("json");

    // Three processes with distinct PIDs, none of them the launcher, all exited cleanly.
    let pids: Vec<u64> = ["sim", "learner", "estimator"]
        .iter()
        .map(|p| summary["pids"][p].as_u64().expect("pid"))
        .collect();
    assert!(
        pids[0] != pids[1] && pids[1] != pids[2] && pids[0] != pids[2],
        "{pids:?}"
    );
    for p in ["sim", "learner", "estimator"] {
        assert_eq!(summary["exit"][p], "exit status: 0", "{p}: {summary}");
    }
    // The learner trained on at least 2 rollouts: one metrics row per update.
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).expect("metrics.csv");
    let updates = metrics.lines().count() - 1; // minus the header
    assert!(updates >= 2, "{metrics}");
    // The sim acted with at least 2 policy versions (0, 1, … as updates arrived).
    assert!(
        summary["policy_version"].as_u64().expect("version") >= 2,
        "{summary}"
    );
    // The estimator published estimates that the launcher could score.
    assert!(summary["terrain_accuracy"].as_f64().is_some(), "{summary}");
    assert_eq!(summary["env_steps"].as_u64(), Some(3072));
    // Checkpoints were written and nothing of the run is left in shared memory.
    assert!(
        std::fs::read_dir(dir.join("checkpoints"))
            .expect("checkpoints")
            .count()
            >= 1
    );
    assert!(
        common::ipc::run_files(&run_id).is_empty(),
        "{:?}",
        common::ipc::run_files(&run_id)
    );
}

#[test]
fn two_specialists_learn_side_by_side_on_their_own_terrain() {
    let run_id = format!("spec-{}", std::process::id());
    let (code, output) = support::lavatube_run("tests/fixtures/specialists.toml", &run_id);
    assert_eq!(code, 0, "launcher output:\n{output}");
    let dir = support::root().join("target/e2e-runs").join(&run_id);
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("summary.json")).expect("summary.json"),
    )
    .expect("json");
    for p in ["sim", "learner-flat", "learner-rough", "estimator"] {
        assert_eq!(summary["exit"][p], "exit status: 0", "{p}: {summary}");
    }
    for slot in ["learner-flat", "learner-rough"] {
        let metrics = std::fs::read_to_string(dir.join(slot).join("metrics.csv"))
            .unwrap_or_else(|e| panic!("{slot} metrics: {e}"));
        assert!(metrics.lines().count() >= 2, "{slot} trained:\n{metrics}");
        let log = std::fs::read_to_string(dir.join("logs").join(format!("{slot}.log")))
            .expect("learner log");
        assert!(log.contains("learner starts a new policy"), "{log}");
    }
}

#[test]
fn a_run_id_in_use_by_a_live_run_is_refused_before_anything_starts() {
    let run_id = format!("busy-{}", std::process::id());
    // This test process holds a launcher's node on the run's bus, as a live run would. (A
    // monitor's node, like tests/survival.rs's, does not take the id.)
    let bus = common::ipc::Bus::connect(&run_id, "launcher").expect("node");
    let (code, output) = support::lavatube_run("configs/smoke.toml", &run_id);
    assert_ne!(code, 0, "{output}");
    assert!(
        output.contains(&format!(
            "run id `{run_id}` is in use by a live run (launcher (pid {})",
            std::process::id()
        )),
        "{output}"
    );
    assert!(
        !support::root()
            .join("target/e2e-runs")
            .join(&run_id)
            .exists(),
        "nothing started"
    );
    drop(bus);
    common::ipc::remove_run(&run_id).expect("clean");
}
