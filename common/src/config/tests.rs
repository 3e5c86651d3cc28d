//! Tests of the config as a whole: defaults, parse errors, ranges across sections, paths.

use super::*;

/// Parses and validates `text`, labelled `t.toml`.
pub(super) fn parse(text: &str) -> Result<Config, ConfigError> {
    let c = Config::parse(text, Path::new("t.toml"))?;
    c.validate()?;
    Ok(c)
}

#[test]
fn defaults_are_valid_and_round_trip() {
    let c = Config::default();
    c.validate().expect("default config valid");
    let back = parse(&c.to_toml()).expect("round trip");
    assert_eq!(back, c);
    assert!((c.sim.decision_dt() - 0.1).abs() < 1e-12);
}

#[test]
fn unknown_key_names_its_line() {
    let e = parse("[sim]\nenvs = { flat = 2 }\nwheel = 3\n").expect_err("unknown");
    let msg = e.to_string();
    assert!(
        msg.starts_with("t.toml:3:1: unknown field `wheel`"),
        "{msg}"
    );
    assert!(!msg.contains('\n'));
}

#[test]
fn out_of_range_names_the_field() {
    let e = parse("[sim.robot]\nwheel-radius = 2.0\n").expect_err("range");
    assert_eq!(
        e.to_string(),
        "config field `sim.robot.wheel-radius` = 2.0: must be in [0.01, 0.2]"
    );
    let e = parse("[sim]\nenvs = { flat = 0 }\n").expect_err("no envs");
    assert!(e.to_string().contains("sim.envs"), "{e}");
    let e = parse("[sim]\nenvs = { flat = 2000 }\n").expect_err("too many");
    assert_eq!(
        e.to_string(),
        "config field `sim.envs` = 2000: for flat, must be in [0, 1024]"
    );
    let e = parse("[sim]\nenvs = { ice = 2 }\n").expect_err("no such area");
    assert!(e.to_string().contains("unknown variant `ice`"), "{e}");
    let e = parse("[reproduce]\neval-roughness-scale = 2.5\n").expect_err("range");
    assert_eq!(
        e.to_string(),
        "config field `reproduce.eval-roughness-scale` = 2.5: must be in [0, 2]"
    );
    let e = parse("[reproduce]\nmargin-s = -0.1\n").expect_err("negative margin");
    assert!(e.to_string().contains("reproduce.margin-s"), "{e}");
    let e = parse("[ppo]\ncheckpoint-every = 4\nmilestone-every = 10\n").expect_err("unwritten");
    assert_eq!(
        e.to_string(),
        "config field `ppo.milestone-every` = 10: must be a multiple of ppo.checkpoint-every (4): only written checkpoints can be kept"
    );
    let e = parse("[reproduce]\ncollect-envs = 0\n").expect_err("no robots");
    assert_eq!(
        e.to_string(),
        "config field `reproduce.collect-envs` = 0: must be in [1, 512]"
    );
    let e = parse("[reproduce]\nspecialist-candidates = 101\n").expect_err("range");
    assert!(
        e.to_string().contains("reproduce.specialist-candidates"),
        "{e}"
    );
    let e = parse("[sim]\nleave-dwell = { sand = 0 }\n").expect_err("range");
    assert_eq!(
        e.to_string(),
        "config field `sim.leave-dwell` = 0: for sand, must be in [1, 10000]"
    );
    let e = parse("[sim]\nleave-dwell = { dune = 5 }\n").expect_err("unknown slot");
    assert!(e.to_string().contains("dune"), "{e}");
    let e = parse("[sim.task]\nepisodes = \"reset\"\n").expect_err("unknown start");
    assert!(
        e.to_string().contains("chained") && e.to_string().contains("course"),
        "{e}"
    );
}

#[test]
fn heightmap_path_survives_being_rewritten_elsewhere() {
    let dir = std::env::temp_dir().join(format!("lavatube-hm-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("run")).expect("dirs");
    std::fs::write(dir.join("floor.grid"), "2 2\n0 0\n0 0\n").expect("grid");
    let cfg_path = dir.join("c.toml");
    let body = "[sim.terrain.heightmap]\npath = \"floor.grid\"\nmetres-per-pixel = 0.1\norigin = [0.0, 0.0]\n";
    std::fs::write(&cfg_path, body).expect("config");
    let cfg = Config::load(&cfg_path).expect("relative to the config file");
    let hm = cfg.sim.terrain.heightmap.clone().expect("heightmap");
    assert!(hm.path.is_absolute() && hm.path.exists(), "{:?}", hm.path);
    // The launcher writes the resolved config into the run directory; children load it there.
    let resolved = dir.join("run/config.toml");
    std::fs::write(&resolved, cfg.to_toml()).expect("resolved");
    assert_eq!(Config::load(&resolved).expect("still found"), cfg);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_partial_imu_table_keeps_each_sensors_own_defaults() {
    let c = parse(
        "[sim]\nobservation = \"imu\"\nphysics-dt = 0.02\nsubsteps = 5\n[sim.imu.accel]\nbits = 12\n[sim.imu.filter]\nkp = 2.0\n",
    )
    .expect("partial tables");
    assert_eq!(c.sim.observation, AttitudeSource::Imu);
    assert_eq!(c.sim.imu.accel.bits, 12);
    // The accelerometer's other fields and the gyroscope keep their own defaults.
    assert_eq!(
        c.sim.imu.accel.range,
        SensorErrors::<Accel>::default().range
    );
    assert_eq!(c.sim.imu.gyro, SensorErrors::<Gyro>::default());
    assert_eq!((c.sim.imu.filter.kp, c.sim.imu.filter.ki), (2.0, 0.05));
    let e = parse("[sim.imu.filter]\ngate = 0.0\n").expect_err("range");
    assert!(e.to_string().contains("sim.imu.filter.gate"), "{e}");
    let e = parse("[sim.imu.gyro]\nbits = 40\n").expect_err("range");
    assert!(e.to_string().contains("sim.imu.gyro.bits"), "{e}");
    let e = parse("[sim]\nobservation = \"gps\"\n").expect_err("unknown source");
    assert!(e.to_string().contains("unknown variant `gps`"), "{e}");
}

#[test]
fn the_estimators_imu_signal_needs_the_imu_simulated() {
    let e = parse("[estimator]\nsignal = \"imu\"\n").expect_err("no IMU");
    assert!(
        e.to_string().contains("estimator.signal")
            && e.to_string().contains("sim.imu.simulate = true"),
        "{e}"
    );
    for with_imu in [
        "[sim]\nobservation = \"imu\"\nphysics-dt = 0.02\nsubsteps = 5\n",
        "[sim]\nphysics-dt = 0.02\nsubsteps = 5\n[sim.imu]\nsimulate = true\n",
    ] {
        let c = parse(&format!("{with_imu}[estimator]\nsignal = \"imu\"\n")).expect(with_imu);
        assert!(c.sim.simulates_imu() && c.estimator.signal == AttitudeSource::Imu);
    }
    assert!(!Config::default().sim.simulates_imu());
}

#[test]
fn a_simulated_imu_needs_a_physics_step_of_at_most_20_ms() {
    // The default step, 1/30 s, is too long for the IMU: one line names the field and the fix.
    for text in [
        "[sim]\nobservation = \"imu\"\n",
        "[sim]\nphysics-dt = 0.025\nsubsteps = 4\n[sim.imu]\nsimulate = true\n",
    ] {
        let e = parse(text).expect_err(text);
        assert!(
            e.to_string().contains("sim.physics-dt") && e.to_string().contains("= 0.02"),
            "{e}"
        );
    }
    let c =
        parse("[sim]\nobservation = \"imu\"\nphysics-dt = 0.02\nsubsteps = 5\n").expect("50 Hz");
    assert_eq!(c.sim.decision_dt(), 0.1);
    assert!((Config::default().sim.decision_dt() - 0.1).abs() < 1e-12);
}

#[test]
fn a_config_extends_another_and_overrides_only_its_own_keys() {
    let dir = tempfile::tempdir().expect("tempdir");
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        path
    };
    write(
        "base.toml",
        "[run]\nseed = 7\n[sim]\nthreads = 1\nenvs = { flat = 2, rough = 3 }\n[sim.task]\nstall-steps = 50\n",
    );
    let top = write(
        "top.toml",
        "extends = \"base.toml\"\n[sim]\nenvs = { rough = 1 }\nobservation = \"imu\"\nphysics-dt = 0.02\nsubsteps = 5\n",
    );
    let c = Config::load(&top).expect("extended");
    assert_eq!((c.run.seed, c.sim.threads), (7, 1));
    // A table-valued field is one value: the top's env counts replace the base's.
    assert_eq!(c.sim.describe_envs(), "0 flat + 1 rough envs");
    assert_eq!(c.sim.observation, AttitudeSource::Imu);
    assert_eq!(c.sim.task.stall_steps, 50);
    let cycle = write("cycle.toml", "extends = \"cycle.toml\"\n");
    let e = Config::load(&cycle).expect_err("cycle");
    assert!(e.to_string().contains("`extends`"), "{e}");
    let bad = write("bad.toml", "extends = \"base.toml\"\n[sim]\ncolour = 1\n");
    let e = Config::load(&bad).expect_err("unknown field");
    assert!(e.to_string().contains("colour"), "{e}");
    let missing = write("missing.toml", "extends = \"nope.toml\"\n");
    let e = Config::load(&missing).expect_err("missing base");
    assert!(e.to_string().contains("nope.toml"), "{e}");
}

#[test]
fn terrain_areas_are_a_list_of_kinds_and_envs_need_their_kinds_area() {
    let e = parse("[sim]\nenvs = { slope = 2 }\n").expect_err("no slope area");
    assert_eq!(
        e.to_string(),
        "config field `sim.envs.slope` = 2: needs a `slope` area in sim.terrain.areas"
    );
    let two_flat = "[sim.terrain]\nareas = [{ kind = \"flat\", x = [0, 1], z = [0, 1] }, { kind = \"flat\", x = [2, 3], z = [0, 1] }]\n";
    let e = parse(two_flat).expect_err("two flat areas");
    assert_eq!(
        e.to_string(),
        "config field `sim.terrain.areas` = \"flat\": holds at most one area per kind"
    );
    let mixed = "[sim.terrain]\nmixed-parts = [{ kind = \"mixed\", x = [0, 1], z = [0, 1] }]\n";
    let e = parse(mixed).expect_err("mixed is no kind");
    assert!(e.to_string().contains("not a terrain kind"), "{e}");
    let upside_down = "[sim.terrain]\nareas = [{ kind = \"flat\", x = [1, 0], z = [0, 1] }]\n";
    let e = parse(upside_down).expect_err("min > max");
    assert!(e.to_string().contains("min < max"), "{e}");
    let c = parse(
        "[sim]\nenvs = { gravel = 2, flat = 1 }\n[sim.terrain]\nareas = [{ kind = \"flat\", x = [0, 1], z = [0, 1] }, { kind = \"gravel\", x = [2, 3], z = [0, 1] }]\n",
    )
    .expect("gravel world");
    assert_eq!(c.sim.num_envs(), 3);
    assert_eq!(c.sim.area_of(2), AreaKind::Gravel);
}

#[test]
fn the_old_env_count_keys_are_refused_with_the_table_that_replaces_them() {
    let e = parse("[sim]\nflat-envs = 4\nrough-envs = 4\nthreads = 1\n").expect_err("old keys");
    assert_eq!(
        e.to_string(),
        "config field `sim.flat-envs` = 4: env counts are one table: write `envs = { flat = 4, rough = 4 }` under [sim]"
    );
    assert!(
        parse("[reproduce]\nflat-envs = 4\n").is_ok(),
        "stage a's count is no area's"
    );
}
