//! The `analyze`, `online` and `kinds` commands end to end on a synthetic recording: flat
//! envs with small pitch noise, rough envs with larger, slope envs tilted, written as a real
//! telemetry CSV.

use common::{AreaKind, TelemetryRow};
use std::path::{Path, PathBuf};
use std::process::Command;

/// 3 flat and 3 rough envs, 500 ticks each, rows interleaved by tick as the sim writes them.
/// Pitch is an AR(1) walk (correlated like a driving robot's) with area-dependent noise.
fn write_traces(dir: &Path) -> PathBuf {
    write_kinds(dir, &[AreaKind::Flat, AreaKind::Rough], 42)
}

/// [`write_traces`] with 3 envs per kind of `kinds`, noise from `seed`; a slope's robots drive
/// as on flat ground, rolled 0.2 rad.
fn write_kinds(dir: &Path, kinds: &[AreaKind], seed: u64) -> PathBuf {
    let path = dir.join("traces.csv");
    let mut w = csv::Writer::from_path(&path).expect("csv");
    let mut rng = common::Rng::new(seed);
    let mut pitch = vec![0.0f64; 3 * kinds.len()];
    for tick in 0..500u64 {
        for env in 0..pitch.len() as u32 {
            let area = kinds[env as usize / 3];
            let noise = if area == AreaKind::Rough { 0.05 } else { 0.012 };
            let p = &mut pitch[env as usize];
            *p = 0.6 * *p + noise * rng.normal();
            let tilt = if area == AreaKind::Slope { 0.2 } else { 0.0 };
            let theta_z = tilt + 0.5 * *p + 0.01 * rng.normal();
            w.serialize(TelemetryRow {
                env,
                tick,
                area,
                episode: tick / 100,
                // Driving at 5 cm/s: every window counts (estimator.min-speed).
                x: 0.005 * tick as f64,
                y: 0.0,
                z: 0.0,
                theta_x: p.asin(),
                theta_y: 0.0,
                theta_z,
                sin_pitch: *p,
                action_left: 1.0,
                action_right: 1.0,
                reward: 0.0,
                terminated: false,
                truncated: false,
                success: false,
                target_x: 0.0,
                target_z: 0.0,
                // The IMU's view: the same pitch with sensor noise.
                imu_theta_x: p.asin() + 0.001 * rng.normal(),
                imu_theta_y: 0.0,
                imu_theta_z: theta_z,
                imu_sin_pitch: *p + 0.001 * rng.normal(),
                ..TelemetryRow::default()
            })
            .expect("row");
        }
    }
    w.flush().expect("flush");
    path
}

/// `estimator-proc analyze TRACES --out OUT` with `args`, in process; its results.json.
fn analyze(traces: &Path, out: &Path, args: &[&str]) -> serde_json::Value {
    command("analyze", traces, out, args, "results.json")
}

/// `estimator-proc kinds TRACES --out OUT` with `args`, in process; its kinds.json.
fn kinds(traces: &Path, out: &Path, args: &[&str]) -> serde_json::Value {
    command("kinds", traces, out, args, "kinds.json")
}

/// `estimator-proc NAME TRACES ARGS --out OUT`, in process; the JSON file it wrote.
fn command(name: &str, traces: &Path, out: &Path, args: &[&str], json: &str) -> serde_json::Value {
    let argv = ["estimator-proc", name, traces.to_str().expect("utf8")]
        .into_iter()
        .chain(args.iter().copied())
        .chain(["--out", out.to_str().expect("utf8")]);
    let cli = <estimator_proc::Cli as clap::Parser>::try_parse_from(argv).expect("args");
    estimator_proc::run(cli).expect(name);
    let text = std::fs::read_to_string(out.join(json)).expect("json");
    serde_json::from_str(&text).expect("valid json")
}

fn finite_numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .inspect(|x| assert!(x.is_finite()))
        .collect()
}

#[test]
fn analyze_writes_results_table_and_four_figures() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let traces = write_traces(tmp.path());
    let out = tmp.path().join("report");
    let json = analyze(&traces, &out, &["--windows", "70,10,20,40"]);
    assert_eq!(json["series"]["flat"], 3);
    assert_eq!(json["warmup_ticks"], 100);
    let windows = json["windows"].as_array().expect("windows");
    let sizes: Vec<u64> = windows
        .iter()
        .map(|w| w["window"].as_u64().expect("window"))
        .collect();
    assert_eq!(sizes, vec![10, 20, 40, 70]);
    for w in windows {
        let size = w["window"].as_u64().expect("window") as usize;
        let n = w["n"].as_u64().expect("n") as usize;
        assert_eq!(
            n,
            6 * (400 - size + 1),
            "SPEC S7: warm-up dropped, windows within series"
        );
        let means = finite_numbers(&w["means"]);
        let weights = finite_numbers(&w["weights"]);
        finite_numbers(&w["stds"]);
        assert!(means[0] < means[1]);
        assert!((weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let accuracy = w["accuracy"].as_f64().expect("accuracy");
        assert!(accuracy > 0.95, "window {size}: accuracy {accuracy}");
        let total: u64 = w["confusion"]
            .as_array()
            .expect("rows")
            .iter()
            .flat_map(|r| r.as_array().expect("row"))
            .map(|c| c.as_u64().expect("count"))
            .sum();
        assert_eq!(total as usize, n);
    }
    let md = std::fs::read_to_string(out.join("results.md")).expect("md");
    assert!(
        md.contains("| window | flat mean (std) / rough mean (std) | accuracy |"),
        "{md}"
    );
    assert!(md.contains("98.79 %"), "paper column beside ours");
    assert!(!md.contains("NaN"));
    for fig in [
        "fig5_sin_roll.png",
        "fig6_sin_pitch.png",
        "fig7_std_distribution_w100.png",
        "fig8_confusion_w10_w70.png",
    ] {
        let bytes = std::fs::read(out.join(fig)).unwrap_or_else(|e| panic!("{fig}: {e}"));
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000,
            "{fig}"
        );
    }
}

#[test]
fn online_replay_reports_accuracy_and_delay() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let traces = write_traces(tmp.path());
    let out = tmp.path().join("online");
    let args = [
        "estimator-proc",
        "online",
        traces.to_str().expect("utf8"),
        "--windows",
        "10,40",
        "--splice",
        "--out",
        out.to_str().expect("utf8"),
    ];
    let cli = <estimator_proc::Cli as clap::Parser>::try_parse_from(args).expect("args");
    estimator_proc::run(cli).expect("online");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("online.json")).expect("json"))
            .expect("valid json");
    for w in json["windows"].as_array().expect("windows") {
        assert!(
            w["filtered"]["accuracy"].as_f64().expect("accuracy") > 0.8,
            "{w}"
        );
        assert_eq!(w["filtered"]["delay"]["changes"], 6, "{w}");
        assert!(
            w["filtered"]["delay"]["detected"]
                .as_u64()
                .expect("detected")
                >= 5,
            "{w}"
        );
    }
    assert!(out.join("online.md").exists());
}

/// `estimator-proc kinds TRACES` with `flag PATH` refused: its error, which must be one line,
/// and nothing written to the output directory.
fn kinds_refused(dir: &Path, traces: &Path, flag: &str, path: &Path) -> String {
    let out = dir.join("o");
    let argv = [
        "estimator-proc",
        "kinds",
        traces.to_str().expect("utf8"),
        flag,
        path.to_str().expect("utf8"),
        "--out",
        out.to_str().expect("utf8"),
    ];
    let cli = <estimator_proc::Cli as clap::Parser>::try_parse_from(argv).expect("args");
    let msg = format!("{:#}", estimator_proc::run(cli).expect_err("refused"));
    assert!(!msg.contains('\n'), "{msg}");
    assert!(!out.exists(), "nothing written: {msg}");
    msg
}

#[test]
fn a_broken_model_file_is_named_in_one_line() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let traces = write_traces(tmp.path());
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, "{\"windows\": [{\"window\": 70}]}").expect("write");
    let msg = kinds_refused(tmp.path(), &traces, "--model", &bad);
    assert!(msg.contains("bad.json: not a kinds.json model"), "{msg}");
}

#[test]
fn more_components_than_the_mixture_takes_are_refused_in_one_line() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let three = [AreaKind::Flat, AreaKind::Rough, AreaKind::Slope];
    let traces = write_kinds(tmp.path(), &three, 42);
    let config = tmp.path().join("c.toml");
    std::fs::write(&config, "[estimator]\ncomponents-per-kind = 6\n").expect("write");
    let msg = kinds_refused(tmp.path(), &traces, "--config", &config);
    assert!(
        msg.contains("components-per-kind = 6 with 3 kinds asks for 18"),
        "{msg}"
    );
}

#[test]
fn the_binary_exits_1_with_one_line_on_bad_input() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let bad = tmp.path().join("bad.csv");
    std::fs::write(&bad, "env,tick,area\n0,0,flat\n").expect("write");
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_estimator-proc"))
            .args(args)
            .output()
            .expect("spawn")
    };
    let out_dir = tmp.path().join("o");
    let o = run(&[
        "analyze",
        bad.to_str().expect("utf8"),
        "--out",
        out_dir.to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("missing column `episode`"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    let o = run(&["analyze", "x.csv", "--windows", "1", "--out", "o"]);
    assert_eq!(o.status.code(), Some(1));
    let o = run(&[
        "analyze",
        "/nonexistent.csv",
        "--out",
        out_dir.to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot read /nonexistent.csv"));
    assert_eq!(run(&["--help"]).status.code(), Some(0));
}

#[test]
fn one_recording_is_scored_on_the_true_and_on_the_imu_pitch() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let traces = write_traces(tmp.path());
    let means = |signal: &str| {
        let out = tmp.path().join(signal);
        let json = analyze(&traces, &out, &["--windows", "70", "--signal", signal]);
        assert_eq!(json["signal"], signal);
        finite_numbers(&json["windows"][0]["means"])
    };
    let (truth, imu) = (means("truth"), means("imu"));
    // The IMU's columns carry extra noise: every window's std, and so each mean, is larger.
    assert!(imu[0] > truth[0] && imu[1] > truth[1], "{truth:?} {imu:?}");
}

#[test]
fn kinds_with_the_papers_one_feature_scores_as_analyze_does() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let traces = write_traces(tmp.path());
    let paper = analyze(&traces, &tmp.path().join("a"), &["--windows", "10,70"]);
    let ours = kinds(&traces, &tmp.path().join("k"), &["--windows", "10,70"]);
    for (p, k) in paper["windows"]
        .as_array()
        .expect("windows")
        .iter()
        .zip(ours["windows"].as_array().expect("windows"))
    {
        assert_eq!(p["window"], k["window"]);
        assert_eq!(p["accuracy"], k["accuracy"], "the same fit, the same score");
        assert_eq!(k["component_kinds"], serde_json::json!(["flat", "rough"]));
    }
}

#[test]
fn kinds_tells_a_slope_by_its_tilt_where_the_papers_feature_cannot() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let three = [AreaKind::Flat, AreaKind::Rough, AreaKind::Slope];
    let traces = write_kinds(tmp.path(), &three, 42);
    let config = tmp.path().join("c.toml");
    std::fs::write(
        &config,
        "[estimator]\nfeatures = [\"pitch-std\", \"mean-tilt\"]\n",
    )
    .expect("config");
    let c = config.to_str().expect("utf8");
    let json = kinds(
        &traces,
        &tmp.path().join("k"),
        &["--config", c, "--windows", "70"],
    );
    let w = &json["windows"][0];
    assert_eq!(w["kinds"], serde_json::json!(["flat", "rough", "slope"]));
    let macro_accuracy = w["macro_accuracy"].as_f64().expect("macro");
    assert!(macro_accuracy > 0.95, "{macro_accuracy}");
    // Without the tilt, slope and flat pitch alike: at most two of three kinds come out.
    let ablation = json["ablation"].as_array().expect("ablation");
    let without_tilt = ablation
        .iter()
        .find(|a| a["without"] == "mean-tilt")
        .expect("tilt left out");
    let blind = without_tilt["macro_accuracy"].as_f64().expect("macro");
    assert!(blind < 0.8, "{blind}");
    assert!(json["windows"][0]["model"]["several"]["means"].is_array());
    // The model and its naming, read back, score another recording without fitting.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).expect("dir");
    let held_out = write_kinds(&other, &three, 7);
    let model = tmp.path().join("k").join("kinds.json");
    let m = model.to_str().expect("utf8");
    let scored = kinds(
        &held_out,
        &tmp.path().join("h"),
        &["--config", c, "--model", m],
    );
    let h = &scored["windows"][0];
    assert!(h["fit"].is_null(), "scored, not fitted");
    assert_eq!(h["component_kinds"], w["component_kinds"]);
    let held_out_accuracy = h["macro_accuracy"].as_f64().expect("macro");
    assert!(held_out_accuracy > 0.95, "{held_out_accuracy}");
    for fig in ["fig_kinds_confusion.png", "fig_kinds_scatter_w70.png"] {
        let bytes =
            std::fs::read(tmp.path().join("k").join(fig)).unwrap_or_else(|e| panic!("{fig}: {e}"));
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000,
            "{fig}"
        );
    }
}
