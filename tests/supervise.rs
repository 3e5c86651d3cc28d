//! The launcher's supervision on fixture processes (`/bin/sh` scripts): the stop ladder ends a
//! process that ignores SIGTERM with SIGKILL, and restart policies restart a failing process
//! exactly as often as configured, within a window that renews.

use common::config::{Restart, RestartPolicy};
use indicatif::ProgressBar;
use lavatube::runtime::{Child, Event, Lines, Output, Role, Spec, Supervised, ladder};
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
        Output::Relay(&bar, Lines::All),
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
    let spec = Spec {
        role: Role::Estimator,
        bin: PathBuf::from("/bin/sh"),
        args: sh("echo started; exit 3"),
        policy: RestartPolicy {
            restart: Restart::OnFailure,
            max_restarts: 2,
            backoff_ms: 10,
            window_s: 0,
        },
    };
    let (slot, events) = supervise_to_the_end(spec, logs.path());
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

#[test]
fn the_restart_budget_renews_once_restarts_leave_its_window() {
    let logs = tempfile::tempdir().expect("tempdir");
    let count = logs.path().join("count");
    // The first three runs fail after 1.1 s, each once the previous restart has left the
    // 1 s window; the fourth fails at once, within the window of the third restart.
    let script = format!(
        "n=$(cat {c} 2>/dev/null || echo 0); echo $((n + 1)) > {c}; [ $n -lt 3 ] && sleep 1.1; exit 3",
        c = count.display()
    );
    let spec = Spec {
        role: Role::Estimator,
        bin: PathBuf::from("/bin/sh"),
        args: sh(&script),
        policy: RestartPolicy {
            restart: Restart::OnFailure,
            max_restarts: 1,
            backoff_ms: 10,
            window_s: 1,
        },
    };
    let (slot, events) = supervise_to_the_end(spec, logs.path());
    assert_eq!(
        events,
        [
            "restart in 10 ms after Some(3)",
            "restarted",
            "restart in 10 ms after Some(3)",
            "restarted",
            "restart in 10 ms after Some(3)",
            "restarted",
            "exited Some(3)",
        ],
        "a restart that left the window frees its place, and resets the backoff"
    );
    assert_eq!(
        slot.restarts, 3,
        "three restarts over the run, one at a time in the window"
    );
}

/// Watches `spec`'s process, restarts and all, until it exits for good; returns what it saw.
fn supervise_to_the_end(spec: Spec, logs: &Path) -> (Supervised, Vec<String>) {
    let bar = ProgressBar::hidden();
    let mut slot = Supervised::start(spec, logs, &bar, Lines::All).expect("start");
    let mut events = Vec::new();
    let give_up = Instant::now() + Duration::from_secs(30);
    while slot.alive() {
        assert!(Instant::now() < give_up, "{events:?}");
        if let Some(e) = slot.watch(logs, &bar, true).expect("watch") {
            events.push(match e {
                Event::Restarting { status, after, .. } => {
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
    (slot, events)
}
