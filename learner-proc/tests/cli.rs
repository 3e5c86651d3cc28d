//! The real `learner-proc` binary on real checkpoint files: output and exit codes.

use std::process::Command;

use common::config::Config;
use common::policy::{PolicyLayout, Scratch};
use common::{ACT_DIM, OBS_DIM, Transition};
use learner_proc::{Learner, Rollout};

fn learner_proc(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_learner-proc"))
        .args(args)
        .output()
        .expect("run learner-proc")
}

/// A 16-16 learner with one epoch, and 128 transitions of 2 envs with rewards 0, 1, 2, ….
fn small_learner(seed: u64) -> (Learner, Vec<Transition>) {
    let mut cfg = Config::default();
    cfg.ppo.hidden = vec![16, 16];
    cfg.ppo.epochs = 1;
    let layout = PolicyLayout::new(OBS_DIM, &[16, 16], ACT_DIM);
    let learner = Learner::new(&cfg, layout, seed).expect("learner");
    let transitions = (0..128)
        .map(|i| Transition {
            env: i % 2,
            reward: (i % 3) as f32,
            ..Transition::default()
        })
        .collect();
    (learner, transitions)
}

const BOOTSTRAP: [[f32; OBS_DIM]; 2] = [[0.0; OBS_DIM]; 2];

fn rollout(transitions: &[Transition]) -> Rollout<'_> {
    Rollout {
        transitions,
        bootstrap_obs: &BOOTSTRAP,
        episodes: &[],
    }
}

#[test]
fn inspect_prints_counters_and_refuses_damage() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut learner, transitions) = small_learner(1);
    learner.update(&rollout(&transitions)).expect("update");
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

/// `plot` on a metrics CSV the learner wrote, then on a damaged copy: a PNG, then a one-line
/// user error naming the file, the line and the column.
#[test]
fn plot_draws_a_png_and_names_a_bad_value() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut learner, transitions) = small_learner(2);
    let rollout = rollout(&transitions);
    let mut log = learner_proc::MetricsLog::open(dir.path()).expect("metrics");
    for _ in 0..3 {
        log.append(&learner.update(&rollout).expect("update"))
            .expect("append");
    }
    let png = dir.path().join(common::run_dir::CURVES_PNG);
    let out = learner_proc(&[
        "plot".as_ref(),
        "--metrics".as_ref(),
        log.path().as_os_str(),
        "--out".as_ref(),
        png.as_os_str(),
    ]);
    assert!(out.status.success(), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("(3 updates)"));
    assert!(std::fs::read(&png).expect("png").starts_with(b"\x89PNG"));

    let text = std::fs::read_to_string(log.path()).expect("read");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, text.replacen("\n1,128,", "\n1,12x8,", 1)).expect("write");
    let out = learner_proc(&[
        "plot".as_ref(),
        "--metrics".as_ref(),
        bad.as_os_str(),
        "--out".as_ref(),
        png.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("bad.csv: line 2, column `global_step`: \"12x8\" is not a number")
            && stderr.lines().count() == 1,
        "{stderr}"
    );
}

#[test]
fn export_writes_the_published_actor_as_a_policy_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cfg = Config::default();
    let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
    let learner = Learner::new(&cfg, layout.clone(), 3).expect("learner");
    learner.save_checkpoint(dir.path()).expect("save");
    let file = dir.path().join("a.policy");
    let out = learner_proc(&[
        "export".as_ref(),
        dir.path().as_os_str(),
        "--out".as_ref(),
        file.as_os_str(),
    ]);
    assert!(out.status.success(), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("10 -> 128 -> 128 -> 2"));
    let bytes = std::fs::read(&file).expect("policy file");
    let exported = common::Policy::from_bytes(&bytes, &file).expect("parses");
    let published = common::Policy::new(layout, learner.policy_weights(), 10.0).expect("policy");
    let obs = [0.3f32, -1.0, 0.5, 2.0, 0.0, 0.1, -0.2, 0.7, 1.5, -3.0];
    let (mut a, mut b) = ([0.0f32; ACT_DIM], [0.0f32; ACT_DIM]);
    exported.mean_action(&obs, &mut a, &mut Scratch::default());
    published.mean_action(&obs, &mut b, &mut Scratch::default());
    assert_eq!(a, b);
}
