//! `lavatube export` as a robot team runs it: the ONNX actor it writes, run by tract, takes
//! the simulator's actions on 10,000 observations (clipped extremes included), its metadata
//! names the inputs, and bad sources are refused in one line.

mod support;

use common::Rng;
use common::observation::OBS_TERMS;
use common::policy::{Policy, PolicyLayout, Scratch};
use std::path::Path;
use tract_onnx::prelude::*;

const ROWS: usize = 10_000;

/// An actor of the default size (10 -> 128 -> 128 -> 2) with seeded weights large enough
/// that its mean action often passes the action limit, and normalisation stats of its own.
fn write_policy(path: &Path, hidden: &[usize], obs: usize) {
    let layout = PolicyLayout::new(obs, hidden, 2);
    let mut rng = Rng::new(7);
    let mut weights: Vec<f32> = (0..layout.len())
        .map(|_| 0.3 * rng.normal() as f32)
        .collect();
    for i in 0..obs {
        weights[layout.obs_mean() + i] = rng.range(-0.5, 0.5) as f32;
        weights[layout.obs_var() + i] = rng.range(0.01, 4.0) as f32;
    }
    let head = layout.dense_layers().pop().expect("head");
    weights[head.weight..head.bias]
        .iter_mut()
        .for_each(|w| *w *= 2.0);
    let policy = Policy::new(layout, weights, 5.0).expect("layout");
    std::fs::write(path, policy.to_bytes()).expect("policy file");
}

fn export(args: &[&str]) -> (i32, String, String) {
    support::lavatube(&[&["export"], args].concat())
}

/// The check rows: observations and the actions beside them.
fn read_rows(path: &Path) -> Vec<(Vec<f32>, [f32; 2])> {
    let text = std::fs::read_to_string(path).expect("check rows");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let names: Vec<&str> = OBS_TERMS.iter().map(|t| t.name).collect();
    assert_eq!(header[..10], names[..]);
    lines
        .map(|l| {
            let v: Vec<f32> = l.split(',').map(|c| c.parse().expect("number")).collect();
            (v[..10].to_vec(), [v[10], v[11]])
        })
        .collect()
}

#[test]
fn the_onnx_actor_takes_the_simulators_actions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("actor.policy");
    write_policy(&file, &[128, 128], 10);
    let out = dir.path().join("export");
    let rows = ROWS.to_string();
    let (code, stdout, stderr) = export(&[
        file.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
        "--check-rows",
        &rows,
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    let rows = read_rows(&out.join("general.check.csv"));
    assert_eq!(rows.len(), ROWS);

    // The rows are the simulator's forward pass, clipped at the default limit (3 rad/s).
    let bytes = std::fs::read(out.join("general.policy")).expect("policy");
    let policy = Policy::from_bytes(&bytes, &out).expect("policy");
    let mut scratch = Scratch::default();
    let mut mean = [0.0f32; 2];
    for (obs, action) in &rows {
        policy.mean_action(obs, &mut mean, &mut scratch);
        assert_eq!(
            mean.map(|m| m.clamp(-3.0, 3.0).to_bits()),
            action.map(f32::to_bits)
        );
    }
    let clipped = rows
        .iter()
        .filter(|(_, a)| a.iter().any(|a| a.abs() == 3.0))
        .count();
    let free = rows
        .iter()
        .filter(|(_, a)| a.iter().all(|a| a.abs() < 3.0))
        .count();
    assert!(
        clipped > ROWS / 20 && free > ROWS / 20,
        "clipped {clipped}, free {free}"
    );
    let far = rows
        .iter()
        .filter(|(o, _)| o.iter().any(|o| o.abs() > 20.0))
        .count();
    assert!(
        far > ROWS / 5,
        "observations past the normaliser's clip: {far}"
    );

    let model = tract_onnx::onnx()
        .model_for_path(out.join("general.onnx"))
        .expect("tract reads the model")
        .into_optimized()
        .expect("optimised")
        .into_runnable()
        .expect("runnable");
    let flat: Vec<f32> = rows.iter().flat_map(|(o, _)| o.iter().copied()).collect();
    let input: Tensor = tract_ndarray::Array2::from_shape_vec((ROWS, 10), flat)
        .expect("shape")
        .into();
    let result = model.run(tvec!(input.into())).expect("run");
    let actions = result[0].to_plain_array_view::<f32>().expect("f32 output");
    assert_eq!(actions.shape(), &[ROWS, 2]);
    let mut worst = 0.0f32;
    for (r, (_, want)) in rows.iter().enumerate() {
        for (k, w) in want.iter().enumerate() {
            worst = worst.max((actions[[r, k]] - w).abs());
        }
    }
    assert!(worst <= 1e-5, "largest difference {worst}");
}

#[test]
fn the_model_says_what_goes_in_and_comes_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("actor.policy");
    write_policy(&file, &[16], 10);
    let out = dir.path().join("export");
    let (code, stdout, stderr) = export(&[
        file.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    let proto = tract_onnx::onnx()
        .proto_model_for_path(out.join("general.onnx"))
        .expect("protobuf");
    let meta = |key: &str| {
        let entry = proto.metadata_props.iter().find(|p| p.key == key);
        entry.map_or_else(|| panic!("no {key} in the metadata"), |p| p.value.clone())
    };
    assert_eq!(meta("lavatube.slot"), "general");
    assert_eq!(meta("action.unit"), "rad/s");
    let period: f64 = meta("control-period-s").parse().expect("seconds");
    assert!((period - 0.1).abs() < 1e-12, "{period}");
    let terms = meta("observation");
    assert!(OBS_TERMS.iter().all(|t| terms.contains(t.name)), "{terms}");
    let graph = proto.graph.expect("graph");
    assert_eq!(graph.input[0].name, "obs");
    assert_eq!(graph.output[0].name, "action");

    let controller: toml::Table = toml::from_str(
        &std::fs::read_to_string(out.join("controller.toml")).expect("controller.toml"),
    )
    .expect("TOML");
    let period = controller["control-period-s"].as_float().expect("seconds");
    assert!((period - 0.1).abs() < 1e-12, "{period}");
    assert_eq!(
        controller["actors"]["general"].as_str(),
        Some("general.onnx")
    );
}

#[test]
fn bad_sources_are_refused_in_one_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("export");
    let out = out.to_str().expect("utf-8");
    let wrong = dir.path().join("wrong.policy");
    write_policy(&wrong, &[16], 7);
    let empty = dir.path().join("run");
    std::fs::create_dir(&empty).expect("dir");
    std::fs::write(empty.join("config.toml"), "").expect("config");
    let garbage = dir.path().join("garbage.policy");
    std::fs::write(&garbage, b"not a policy").expect("file");
    for (source, says) in [
        (dir.path().join("missing.policy"), "does not exist"),
        (wrong, "7 observations"),
        (empty, "holds no learner checkpoint"),
        (garbage, "bad magic"),
    ] {
        let (code, _, stderr) = export(&[source.to_str().expect("utf-8"), "--out", out]);
        assert_eq!(code, 1, "{}: {stderr}", source.display());
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(stderr.contains(says), "{}: {stderr}", source.display());
    }
}

#[test]
fn a_switching_run_exports_the_checkpoints_it_drove_with() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut cfg = common::Config::default();
    cfg.ppo.hidden = vec![16, 16];
    let layout = PolicyLayout::new(10, &[16, 16], 2);
    let mut frozen = String::new();
    for (slot, seed) in [("flat", 1), ("rough", 2)] {
        let learner = learner_proc::Learner::new(&cfg, layout.clone(), seed).expect("learner");
        let ckpt = learner
            .save_checkpoint(&dir.path().join(slot))
            .expect("checkpoint");
        frozen += &format!("{slot} = {:?}\n", ckpt.to_str().expect("utf-8"));
    }
    let run = dir.path().join("run");
    std::fs::create_dir(&run).expect("run dir");
    let config = format!(
        "[run]\nlearners = []\n\n[run.frozen]\n{frozen}\n[sim]\nacting = \"switch\"\n\n[ppo]\nhidden = [16, 16]\n"
    );
    std::fs::write(run.join("config.toml"), config).expect("config");
    let out = dir.path().join("export");
    let (code, stdout, stderr) = export(&[
        run.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(stdout.contains("2 actors (flat, rough)"), "{stdout}");
    assert!(stdout.contains("fitted online"), "{stdout}");
    for slot in ["flat", "rough"] {
        assert!(out.join(format!("{slot}.onnx")).is_file(), "{slot}");
    }
    assert!(!out.join("general.onnx").exists());
    // The two actors are the two checkpoints: their check rows differ.
    let rows =
        |slot: &str| std::fs::read_to_string(out.join(format!("{slot}.check.csv"))).expect("rows");
    assert_ne!(rows("flat"), rows("rough"));
    let controller = std::fs::read_to_string(out.join("controller.toml")).expect("controller.toml");
    assert!(controller.contains("acting = \"switch\""), "{controller}");
}
