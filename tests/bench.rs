//! `lavatube bench` end to end: `--quick` runs every stage of the matrix as real processes and
//! writes a JSON with every stage × envs × threads entry, the transport ratios and the
//! acceptance checks, and leaves no shared memory; bad input is refused before anything runs.

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Kills the bench if it has not finished in time (the quick matrix takes seconds in release,
/// a few times that in a debug build on a busy machine).
const WATCHDOG: Duration = Duration::from_secs(600);

/// `lavatube ARGS` in `dir`, under the watchdog.
fn lavatube(dir: &Path, args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("launcher starts");
    let started = Instant::now();
    while child.try_wait().expect("poll").is_none() {
        if started.elapsed() > WATCHDOG {
            child.kill().expect("kill");
            panic!("lavatube {args:?} did not finish within {WATCHDOG:?}");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    child.wait_with_output().expect("output")
}

fn positive(v: &Value, what: &str) -> f64 {
    let x = v
        .as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"));
    assert!(x.is_finite() && x > 0.0, "{what} = {x}");
    x
}

#[test]
fn quick_bench_measures_every_stage_and_cleans_up() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json_path = dir.path().join("bench.json");
    let out = lavatube(
        dir.path(),
        &[
            "bench",
            "--quick",
            "--json",
            json_path.to_str().expect("utf-8"),
        ],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "stdout:\n{stdout}\nstderr:\n{stderr}");
    assert!(stdout.contains("stage c ≥ 0.95 × stage b"), "{stdout}");
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).expect("json")).expect("parse");
    assert_eq!(report["schema"], "lavatube.bench.v1");
    assert_eq!(report["quick"], true);
    assert!(report["units"]["*_us"].is_string(), "units are spelled out");

    let stages = report["stages"].as_array().expect("stages");
    assert_eq!(
        stages.len(),
        6 * 3 * 2,
        "one entry per stage × envs × threads"
    );
    for stage in ["a", "b", "c", "d", "e", "f"] {
        for envs in [1u64, 8, 64] {
            for threads in [1u64, 2] {
                let cell = format!("stage {stage}, {envs} envs, {threads} threads");
                let row = stages
                    .iter()
                    .find(|r| r["stage"] == stage && r["envs"] == envs && r["threads"] == threads)
                    .unwrap_or_else(|| panic!("{cell} missing"));
                assert_eq!(
                    row["decision_steps_per_s_repeats"],
                    serde_json::json!([row["decision_steps_per_s"]]),
                    "{cell}: --quick measures once"
                );
                for key in ["decision_steps_per_s", "physics_steps_per_s", "wall_s"] {
                    positive(&row[key], &format!("{cell}: {key}"));
                }
                let procs = row["processes"].as_object().expect("processes");
                let mut want = vec!["sim"];
                if stage >= "c" {
                    want.push("reader");
                    positive(&row["transport_latency_p50_us"], &format!("{cell}: p50"));
                    positive(&row["transport_latency_p99_us"], &format!("{cell}: p99"));
                    positive(&row["telemetry_ticks_received"], &format!("{cell}: ticks"));
                } else {
                    assert!(row["transport_latency_p50_us"].is_null(), "{cell}");
                }
                if stage >= "d" {
                    want.push("learner");
                    positive(&row["learner_samples_per_s"], &format!("{cell}: samples/s"));
                    let lag = row["policy_lag_versions"].as_f64().expect("lag");
                    assert!(lag.is_finite() && lag >= 0.0, "{cell}: lag {lag}");
                } else {
                    assert!(row["learner_samples_per_s"].is_null(), "{cell}");
                }
                if stage == "f" {
                    want.push("estimator");
                }
                let mut names: Vec<&str> = procs.keys().map(String::as_str).collect();
                names.sort_unstable();
                want.sort_unstable();
                assert_eq!(names, want, "{cell}");
                for (name, usage) in procs {
                    positive(&usage["peak_rss_mib"], &format!("{cell}: {name} RSS"));
                    let cpu = usage["cpu_user_s"].as_f64().expect("cpu")
                        + usage["cpu_system_s"].as_f64().expect("cpu");
                    assert!(cpu.is_finite() && cpu >= 0.0, "{cell}: {name} cpu {cpu}");
                }
                positive(&procs["sim"]["cpu_user_s"], &format!("{cell}: sim CPU"));
            }
        }
    }

    // Stages b and c act with the same policy from the same seed: the same episodes end.
    for envs in [1u64, 8, 64] {
        for threads in [1u64, 2] {
            let episodes = |stage: &str| {
                stages
                    .iter()
                    .find(|r| r["stage"] == stage && r["envs"] == envs && r["threads"] == threads)
                    .map(|r| r["episodes"].clone())
            };
            assert_eq!(
                episodes("b"),
                episodes("c"),
                "{envs} envs, {threads} threads"
            );
        }
    }

    let transport = report["transport"].as_array().expect("transport");
    for kind in ["telemetry", "rollout", "weights"] {
        assert!(
            transport.iter().any(|t| t["payload"] == kind),
            "{kind} payload missing"
        );
    }
    for t in transport {
        for side in ["iceoryx2", "uds"] {
            for key in ["latency_p50_us", "latency_p99_us", "messages_per_s"] {
                positive(&t[side][key], &format!("{} {side} {key}", t["payload"]));
            }
        }
        for key in [
            "latency_p50_uds_over_iceoryx2",
            "latency_p99_uds_over_iceoryx2",
            "messages_per_s_iceoryx2_over_uds",
        ] {
            positive(&t["ratios"][key], &format!("{} {key}", t["payload"]));
        }
    }
    let acceptance = &report["acceptance"];
    assert_eq!(
        acceptance["publish_over_policy"].as_array().map(Vec::len),
        Some(6)
    );
    assert_eq!(acceptance["learning"].as_array().map(Vec::len), Some(12));
    for check in acceptance["publish_over_policy"]
        .as_array()
        .expect("checks")
    {
        let ratios = check["ratios"].as_array().expect("ratios");
        assert_eq!(ratios.len(), 1);
        assert_eq!(check["ratio"], ratios[0], "one repeat: its own ratio");
    }

    // Every run of the bench removed its shared memory.
    let bench_id = report["bench_id"].as_str().expect("bench id");
    let left: Vec<String> = common::ipc::runs_with_files()
        .into_iter()
        .filter(|r| r.starts_with(bench_id))
        .collect();
    assert!(left.is_empty(), "shared memory left: {left:?}");
}

#[test]
fn bad_input_is_one_line_before_anything_starts() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (body, expected) in [
        (
            "[bench]\nenvs = [1, 0]\n",
            "lavatube: config field `bench.envs` = [1, 0]: 0 is not in [1, 1024]\n",
        ),
        (
            "[bench]\nenvs = [8]\nthread = [1]\n",
            "lavatube: {path}:3:1: unknown field `thread`, expected one of `runtime`, `envs`, `threads`, `env-steps`, `min-chunks`, `repeats`, `transport-messages`, `timeout-s`, `out-dir`\n",
        ),
    ] {
        let path = dir.path().join("bench.toml");
        std::fs::write(&path, body).expect("write");
        let out = lavatube(
            dir.path(),
            &["bench", "--config", path.to_str().expect("utf-8")],
        );
        let expected = expected.replace("{path}", &path.display().to_string());
        assert_eq!(
            (
                out.status.code(),
                String::from_utf8_lossy(&out.stderr).as_ref(),
                out.stdout.is_empty()
            ),
            (Some(1), expected.as_str(), true)
        );
        assert!(!dir.path().join("runs").exists(), "nothing was started");
    }
    let out = lavatube(dir.path(), &["bench", "--json", "/no/such/dir/bench.json"]);
    assert_eq!(
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).as_ref()
        ),
        (
            Some(1),
            "lavatube: --json: directory /no/such/dir does not exist\n"
        )
    );
    assert!(!dir.path().join("runs").exists(), "nothing was started");
}
