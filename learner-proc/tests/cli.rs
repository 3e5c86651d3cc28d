//! The real `learner-proc` binary on real checkpoint files: output and exit codes.

use std::process::Command;

use common::config::Config;
use common::policy::PolicyLayout;
use common::{ACT_DIM, OBS_DIM, Transition};
use learner_proc::{Learner, Rollout};

fn learner_proc(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_learner-proc"))
        .args(args)
        .output()
        .expect("run learner-proc")
}

#[test]
fn inspect_prints_counters_and_refuses_damage() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut cfg = Config::default();
    cfg.ppo.hidden = vec![16, 16];
    cfg.ppo.epochs = 1;
    let mut learner =
        Learner::new(&cfg, PolicyLayout::new(OBS_DIM, &[16, 16], ACT_DIM), 1).expect("learner");
    let transitions: Vec<Transition> = (0..128)
        .map(|i| Transition {
            env: i % 2,
            ..Transition::default()
        })
        .collect();
    let bootstrap = [[0.0; OBS_DIM]; 2];
    let rollout = Rollout {
        transitions: &transitions,
        bootstrap_obs: &bootstrap,
        episodes: &[],
    };
    learner.update(&rollout).expect("update");
    let path = learner.save_checkpoint(dir.path()).expect("save");

    let out = learner_proc(&["inspect".as_ref(), dir.path().as_os_str()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    assert!(
        stdout.contains("update           1\n") && stdout.contains("global step      128\n"),
        "{stdout}"
    );
    assert!(stdout.contains("10 -> 16 -> 16 -> 2"), "{stdout}");

    let bytes = std::fs::read(&path).expect("read");
    std::fs::write(&path, &bytes[..bytes.len() - 1]).expect("truncate");
    let out = learner_proc(&["inspect".as_ref(), path.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("checkpoint-0000000001.ckpt is corrupt"),
        "{stderr}"
    );

    let out = learner_proc(&["inspect".as_ref(), dir.path().as_os_str()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no loadable checkpoint"));

    let out = learner_proc(&["frobnicate".as_ref()]);
    assert_eq!(out.status.code(), Some(1), "usage errors are user errors");
}
