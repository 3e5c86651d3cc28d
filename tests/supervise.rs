//! The launcher's supervision on fixture processes (`/bin/sh` scripts): the stop ladder ends a
//! process that ignores SIGTERM with SIGKILL, and restart policies restart a failing process
//! exactly as often as configured.

use common::config::{Restart, RestartPolicy};
use indicatif::ProgressBar;
use lavatube::runtime::{Child, Event, Output, Role, Spec, Supervised, ladder};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn sh(script: &str) -> Vec<String> {
    vec!["-c".into(), script.into()]
}

#[test]
fn a_process_that_ignores_sigterm_is_killed_after_the_grace_period() {
    let logs = tempfile::tempdir().expect("tempdir");
    let bar = ProgressBar::hidden();
    let script = sh("trap '' TERM; echo ready; while :; do sleep 0.05; done");
    let mut p = Child::spawn(
        "fixture",
        Path::new("/bin/sh"),
        &script,
        logs.path(),
        Output::Relay(&bar),
    )
    .expect("spawn");
    let log = logs.path().join("fixture.log");
    let ready = Instant::now() + Duration::from_secs(30);
    while !std::fs::read_to_string(&log).is_ok_and(|t| t.contains("ready")) {
        assert!(Instant::now() < ready, "the fixture did not start");
        std::thread::sleep(Duration::from_millis(10));
    }
    let grace = Duration::from_millis(300);
    let started = Instant::now();
    ladder::stop(&mut [&mut p], &|| {}, grace);
    let status = p.status().expect("reaped");
    assert_eq!(status.signal(), Some(libc::SIGKILL), "{status}");
    assert!(
        started.elapsed() >= 2 * grace,
        "a grace period for the request, another after SIGTERM"
    );
}

#[test]
fn a_failing_process_is_restarted_as_often_as_its_policy_allows() {
    let logs = tempfile::tempdir().expect("tempdir");
    let bar = ProgressBar::hidden();
    let spec = Spec {
        role: Role::Estimator,
        bin: PathBuf::from("/bin/sh"),
        args: sh("echo started; exit 3"),
        policy: RestartPolicy {
            restart: Restart::OnFailure,
            max_restarts: 2,
            backoff_ms: 10,
        },
    };
    let mut slot = Supervised::start(spec, logs.path(), &bar).expect("start");
    let mut events = Vec::new();
    let give_up = Instant::now() + Duration::from_secs(30);
    while slot.alive() {
        assert!(Instant::now() < give_up, "{events:?}");
        if let Some(e) = slot.watch(logs.path(), &bar, true).expect("watch") {
            events.push(match e {
                Event::Restarting { status, after } => {
                    format!(
                        "restart in {} ms after {:?}",
                        after.as_millis(),
                        status.code()
                    )
                }
                Event::Restarted { .. } => "restarted".into(),
                Event::Exited(status) => format!("exited {:?}", status.code()),
            });
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(
        events,
        [
            "restart in 10 ms after Some(3)",
            "restarted",
            "restart in 20 ms after Some(3)",
            "restarted",
            "exited Some(3)",
        ]
    );
    assert_eq!(slot.restarts, 2);
    let log = std::fs::read_to_string(logs.path().join("estimator.log")).expect("log");
    assert_eq!(log, "started\n".repeat(3), "restarts append to one log");
}
