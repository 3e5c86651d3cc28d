//! The launcher's command line against bad input: one line naming what is wrong, exit code 1,
//! and nothing started (no run directory, no shared memory).

mod support;

use std::path::PathBuf;
use support::lavatube;

/// A config file in a fresh temp dir (removed when the first value drops) whose out-dir is
/// inside it too.
fn config(body: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bad.toml");
    let out = dir.path().join("runs");
    std::fs::write(
        &path,
        format!("[run]\nout-dir = \"{}\"\n{body}", out.display()),
    )
    .expect("write");
    (dir, path, out)
}

fn assert_refused(name: &str, body: &str, expected: &str) {
    let (_dir, path, out) = config(body);
    let run_id = format!("cli-{name}");
    let (code, stdout, stderr) = lavatube(&[
        "run",
        "--config",
        path.to_str().expect("utf-8"),
        "--run-id",
        &run_id,
        "--quiet",
    ]);
    let expected = expected.replace("{path}", &path.display().to_string());
    assert_eq!(
        (code, stdout.as_str(), stderr.as_str()),
        (1, "", format!("lavatube: {expected}\n").as_str())
    );
    assert!(!out.exists(), "no run directory is created");
    assert!(
        common::ipc::run_files(&run_id).is_empty(),
        "no shared memory is created"
    );
}

#[test]
fn unknown_key_is_refused_with_its_position() {
    assert_refused(
        "unknown",
        "[sim]\nwheels = 3\n",
        "{path}:4:1: unknown field `wheels`, expected one of `envs`, `threads`, `acting`, `external`, `switch-dwell`, `leave-dwell`, `mean-actions`, `telemetry-notify-us`, `gravity`, `physics-dt`, `substeps`, `terrain`, `robot`, `observation`, `imu`, `task`, `randomize`",
    );
}

#[test]
fn out_of_range_value_names_the_field() {
    assert_refused(
        "range",
        "[sim.robot]\nwheel-radius = 2.0\n",
        "config field `sim.robot.wheel-radius` = 2.0: must be in [0.01, 0.2]",
    );
}

#[test]
fn wrong_type_names_its_position() {
    assert_refused(
        "type",
        "[ppo]\nepochs = \"ten\"\n",
        "{path}:4:10: invalid type: string \"ten\", expected usize",
    );
}

#[test]
fn missing_file_is_one_line() {
    let (code, _, stderr) = lavatube(&["run", "--config", "/no/such/lavatube.toml", "--quiet"]);
    assert_eq!(code, 1);
    assert_eq!(
        stderr,
        "lavatube: cannot read config /no/such/lavatube.toml: No such file or directory (os error 2)\n"
    );
}

#[test]
fn check_config_accepts_the_shipped_configs() {
    for f in ["configs/default.toml", "configs/smoke.toml"] {
        let path = format!("{}/{f}", env!("CARGO_MANIFEST_DIR"));
        let (code, stdout, stderr) = lavatube(&["check-config", &path]);
        assert_eq!((code, stderr.as_str()), (0, ""), "{f}");
        assert!(stdout.starts_with(&format!("{path}: ok (")), "{stdout}");
    }
}

#[test]
fn check_config_explains_a_field_and_refuses_an_unknown_one() {
    let (code, stdout, stderr) = lavatube(&["check-config", "--explain", "ppo.clip-coef"]);
    assert_eq!((code, stderr.as_str()), (0, ""));
    assert!(stdout.starts_with("ppo.clip-coef (advanced)\n"), "{stdout}");
    assert!(stdout.contains("default: 0.2\n"), "{stdout}");
    assert!(stdout.contains("accepts: [0.000001, 1]\n"), "{stdout}");
    let (code, _, stderr) = lavatube(&["check-config", "--explain", "ppo.clip"]);
    assert_eq!(code, 1, "an unknown field is a user error");
    assert!(stderr.contains("no config field `ppo.clip`"), "{stderr}");
}

#[test]
fn bad_run_id_is_refused_by_the_parser() {
    let (code, _, stderr) = lavatube(&["run", "--run-id", "a/b"]);
    assert_eq!(code, 1, "usage errors are user errors");
    assert!(
        stderr.contains("run id `a/b` must be 1–32 characters of A-Z a-z 0-9 -"),
        "{stderr}"
    );
}

#[test]
fn analyze_runs_the_estimators_analysis() {
    let dir = std::env::temp_dir().join(format!("lavatube-analyze-{}", std::process::id()));
    let (code, _, stderr) = lavatube(&[
        "analyze",
        "/no/such/traces.csv",
        "--out",
        dir.to_str().expect("utf-8"),
    ]);
    assert_eq!(code, 1, "a missing input is a user error: {stderr}");
    assert!(stderr.contains("/no/such/traces.csv"), "{stderr}");
}

/// `lavatube world export` of a config with `body`: the config's temp dir (held), the OBJ
/// path, and the exit code, stdout and stderr.
fn world_export(body: &str) -> (tempfile::TempDir, PathBuf, (i32, String, String)) {
    let (dir, path, _) = config(body);
    let obj = dir.path().join("floor.obj");
    let ran = lavatube(&[
        "world",
        "export",
        "--config",
        path.to_str().expect("utf-8"),
        "--out",
        obj.to_str().expect("utf-8"),
    ]);
    (dir, obj, ran)
}

#[test]
fn world_export_writes_the_floor_or_refuses_the_config() {
    let (_dir, obj, (code, stdout, stderr)) = world_export("[sim.terrain]\nborder = 0.5\n");
    assert_eq!(code, 0, "{stderr}");
    let text = std::fs::read_to_string(&obj).expect("obj");
    let vertices = text.lines().filter(|l| l.starts_with("v ")).count();
    let faces = text.lines().filter(|l| l.starts_with("f ")).count();
    assert!(
        stdout.contains(&format!("{vertices} vertices, {faces} triangles")),
        "{stdout}"
    );
    assert!(
        vertices > 1000 && faces > vertices,
        "{vertices} vertices, {faces} faces"
    );

    let (_bad, obj, (code, _, stderr)) = world_export("[sim.terrain]\nborder = -1.0\n");
    assert_eq!(code, 1, "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("border"), "{stderr}");
    assert!(!obj.exists());
}
