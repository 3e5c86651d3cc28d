//! DESIGN §2 against a hostile peer: a process on a live run's services publishes rollout
//! chunks with NaN rewards, with env ids out of range, of the wrong size, and a policy with NaN
//! weights. The learner drops each chunk and the sim each policy, count them, log the first
//! of each kind, and keep running; the sim never acts with the poisoned policy.

use common::Transition;
use common::ipc;
use common::run_dir;
use common::wire::{PolicyHeader, RolloutHeader};
use std::time::{Duration, Instant};

mod support;

const CONFIG: &str = "tests/fixtures/survival.toml";
const PATIENCE: Duration = Duration::from_secs(120);
/// The poisoned policy's version: no learner of the run gets near it.
const POISON: u32 = 999_999;

/// Lines of `process`'s log in run directory `dir` that contain every one of `needles`.
fn said(dir: &std::path::Path, process: &str, needles: &[&str]) -> usize {
    std::fs::read_to_string(run_dir::log_file(dir, process))
        .unwrap_or_default()
        .lines()
        .filter(|l| needles.iter().all(|n| l.contains(n)))
        .count()
}

#[test]
fn hostile_messages_are_dropped_counted_and_logged_once_per_kind() {
    let run = format!("hostile-{}", std::process::id());
    let launcher = support::Launched::start(CONFIG, &run);
    let dir = support::root().join("target/e2e-runs").join(&run);
    let watch = support::Watch::connect(&run, "stranger");
    let (bus, ticks, policies) = (&watch.bus, &watch.ticks, &watch.policies);
    let (steps, envs) = (2u32, 4u32);
    let rollout_tx = bus
        .sender::<Transition, RolloutHeader>(&ipc::ROLLOUT, None, 64)
        .expect("rollout sender");

    // The run's first real policy, to learn its shape and its learner.
    let give_up = Instant::now() + PATIENCE;
    let genuine = loop {
        assert!(Instant::now() < give_up, "no policy");
        policies.wait(Duration::from_millis(10)).expect("wait");
        if let Some(p) = policies.try_recv().expect("policy") {
            break (*p.user_header(), p.payload().len());
        }
    };
    let policy_tx = bus
        .sender::<f32, PolicyHeader>(&ipc::POLICY, Some("general"), genuine.1)
        .expect("policy sender");

    let header = RolloutHeader {
        chunk: 1 << 40,
        env_steps: 1 << 40,
        steps,
        envs,
        ..RolloutHeader::default()
    };
    let chunk = |f: &dyn Fn(usize, &mut Transition)| -> Vec<Transition> {
        (0..(steps * envs + envs) as usize)
            .map(|i| {
                let mut t = Transition {
                    env: i as u32 % envs,
                    ..Transition::default()
                };
                f(i, &mut t);
                t
            })
            .collect()
    };
    let nan_reward = chunk(&|i, t| t.reward = if i == 3 { f32::NAN } else { 0.0 });
    let far_env = chunk(&|i, t| {
        if i == 1 {
            t.env = u32::MAX;
        }
    });
    let mut poison = PolicyHeader {
        version: POISON,
        ..genuine.0
    };
    poison.learner = std::process::id();
    let nan_weights = vec![f32::NAN; genuine.1];
    for _ in 0..3 {
        rollout_tx.send(header, &nan_reward).expect("send");
        rollout_tx.send(header, &far_env).expect("send");
        rollout_tx.send(header, &nan_reward[..5]).expect("send");
        policy_tx.send(poison, &nan_weights).expect("send");
        std::thread::sleep(Duration::from_millis(200));
    }

    // The run goes on: the learner (the same process) publishes new versions, the sim ticks,
    // and no tick was acted with the poisoned policy.
    let learner = genuine.0.learner;
    let mut newest = genuine.0.version;
    let mut last_tick = 0;
    let until = Instant::now() + PATIENCE;
    while newest < genuine.0.version + 3 || last_tick == 0 {
        assert!(
            Instant::now() < until,
            "the run stalled after the hostile messages"
        );
        ticks.wait(Duration::from_millis(10)).expect("wait");
        while let Some(t) = ticks.try_recv().expect("telemetry") {
            let h = t.user_header();
            assert_ne!(h.policy_version, POISON, "the sim acted with NaN weights");
            last_tick = h.tick;
        }
        while let Some(p) = policies.try_recv().expect("policy") {
            let h = p.user_header();
            if h.learner == learner {
                newest = newest.max(h.version);
            }
        }
    }
    drop((rollout_tx, policy_tx, watch));
    let (code, out) = launcher.wait_interrupted();
    assert_eq!(code, 130, "the run was still going when interrupted: {out}");

    for (process, kind) in [
        ("learner", "non-finite value"),
        ("learner", "env id out of range"),
        ("learner", "wrong chunk size"),
        ("sim", "non-finite weights"),
    ] {
        let lines = said(&dir, process, &["refused (further", kind]);
        assert_eq!(lines, 1, "{process} logs `{kind}` once, then counts");
    }
    assert!(
        said(&dir, "learner", &["learner done", "non-finite value: 3"]) == 1,
        "the learner's closing line counts every refused chunk"
    );
}
