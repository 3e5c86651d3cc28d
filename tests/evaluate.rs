//! `lavatube evaluate` as a user runs it: policies on the worlds of a file, every policy on
//! the same courses, and bad input refused before anything starts.

mod support;

use common::Rng;
use common::policy::{Policy, PolicyLayout};
use std::path::Path;

/// A small untrained actor (10 -> 16 -> 2) with seeded weights, as a `.policy` file.
fn write_policy(path: &Path, seed: u64) {
    let layout = PolicyLayout::new(10, &[16], 2);
    let mut rng = Rng::new(seed);
    let mut weights: Vec<f32> = (0..layout.len())
        .map(|_| 0.5 * rng.normal() as f32)
        .collect();
    weights[layout.obs_mean()..layout.obs_mean() + 10].fill(0.0);
    weights[layout.obs_var()..layout.obs_var() + 10].fill(1.0);
    let policy = Policy::new(layout, weights, 10.0).expect("layout");
    std::fs::write(path, policy.to_bytes()).expect("policy file");
}

fn evaluate(args: &[&str]) -> (i32, String, String) {
    support::lavatube(&[&["evaluate"], args].concat())
}

#[test]
fn every_policy_drives_the_same_courses_in_every_world() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (policy, other) = (dir.path().join("a.policy"), dir.path().join("b.policy"));
    write_policy(&policy, 1);
    write_policy(&other, 2);
    let worlds = dir.path().join("worlds.toml");
    std::fs::write(
        &worlds,
        "[[world]]\nname = \"nominal\"\n\n[[world]]\nname = \"pushed\"\n\
         sim.randomize.push-impulse = [0.2, 0.3]\nsim.randomize.push-interval = 0.5\n",
    )
    .expect("worlds");
    let out = dir.path().join("eval");
    let same = format!("twin={}", policy.display());
    let (code, stdout, stderr) = evaluate(&[
        "--worlds",
        worlds.to_str().expect("utf-8"),
        "--area",
        "flat",
        "--episodes",
        "4",
        "--envs",
        "2",
        "--out",
        out.to_str().expect("utf-8"),
        policy.to_str().expect("utf-8"),
        &same,
        other.to_str().expect("utf-8"),
    ]);
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(out.join("evaluation.json")).expect("json"))
            .expect("rows");
    assert_eq!(rows.len(), 6, "two worlds × three policies");
    let cell = |world: &str, policy: &str| {
        let r = rows
            .iter()
            .find(|r| r["world"] == world && r["policy"] == policy)
            .expect("row");
        (
            r["episodes"].clone(),
            r["success_pct"].clone(),
            r["reach_s"].clone(),
        )
    };
    for world in ["nominal", "pushed"] {
        // The same policy under two labels drives the same legs to the same ends.
        assert_eq!(cell(world, "a"), cell(world, "twin"), "{world}");
        assert!(cell(world, "a").0.as_u64().expect("episodes") >= 4);
    }
    assert!(stdout.contains("| pushed |"), "{stdout}");
    assert!(out.join("evaluation.png").is_file());
    assert!(out.join("evaluation.md").is_file());
}

#[test]
fn a_bad_world_file_or_policy_is_refused_in_one_line_before_anything_starts() {
    let dir = tempfile::tempdir().expect("tempdir");
    let policy = dir.path().join("a.policy");
    write_policy(&policy, 1);
    let worlds = dir.path().join("worlds.toml");
    let out = dir.path().join("eval");
    for (text, policy_arg, says) in [
        (
            "[[world]]\nname = \"moon\"\nsim.gravity = -1.62\n",
            policy.display().to_string(),
            "world `moon`: config field `sim.gravity`",
        ),
        (
            "[[world]]\nname = \"nominal\"\n",
            "missing.policy".to_string(),
            "missing.policy does not exist",
        ),
        (
            "[[world]]\nname = \"nominal\"\n",
            format!("x={}", dir.path().display()),
            "is not a run directory",
        ),
    ] {
        std::fs::write(&worlds, text).expect("worlds");
        let (code, _, stderr) = evaluate(&[
            "--worlds",
            worlds.to_str().expect("utf-8"),
            "--out",
            out.to_str().expect("utf-8"),
            &policy_arg,
        ]);
        assert_eq!(code, 1, "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(!out.join("evaluation.json").exists());
    }
}
