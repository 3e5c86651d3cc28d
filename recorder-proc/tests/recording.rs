//! Recordings written through the recorder's logging code, read back with the Rerun SDK's
//! own decoder: the entity paths and the ticks logged are the ones written.

use recorder_proc::command::{convert, serve};
use recorder_proc::entity;
use recorder_proc::sample::{EstimateSample, RobotSample};
use recorder_proc::{RecordOptions, Recording};
use rerun::external::re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// What a recording holds, per entity path (without the leading `/`), leaving out Rerun's
/// own entities (`__properties`: the recording's name).
#[derive(Debug, Default)]
struct Decoded {
    statics: BTreeSet<String>,
    /// The `tick` values of each entity's temporal rows, and how many rows there were.
    ticks: BTreeMap<String, BTreeSet<i64>>,
    rows: BTreeMap<String, usize>,
}

impl Decoded {
    fn read(path: &Path) -> Self {
        let file = std::fs::File::open(path).expect("the recording exists");
        let messages =
            DecoderApp::decode_eager(std::io::BufReader::new(file)).expect("an .rrd stream");
        let mut d = Self::default();
        for msg in messages {
            let LogMsg::ArrowMsg(_, arrow) = msg.expect("every message decodes") else {
                continue;
            };
            let chunk = Chunk::from_arrow_msg(&arrow).expect("a chunk");
            let entity = chunk
                .entity_path()
                .to_string()
                .trim_start_matches('/')
                .to_string();
            if entity.starts_with("__") {
                continue;
            }
            if chunk.is_static() {
                d.statics.insert(entity);
                continue;
            }
            let times = chunk
                .timelines()
                .get(&rerun::TimelineName::from_static_str(entity::TIMELINE))
                .unwrap_or_else(|| panic!("{entity} is on the tick timeline"));
            d.ticks
                .entry(entity.clone())
                .or_default()
                .extend(times.times_raw());
            *d.rows.entry(entity).or_default() += chunk.num_rows();
        }
        d
    }

    fn ticks_of(&self, entity: &str) -> Vec<i64> {
        self.ticks
            .get(entity)
            .map(|t| t.iter().copied().collect())
            .unwrap_or_default()
    }
}

fn config(envs: usize) -> common::Config {
    let mut cfg = common::Config::default();
    cfg.sim.only_in(common::AreaKind::Flat, envs);
    cfg
}

fn robot(env: usize, tick: u64) -> RobotSample {
    let t = tick as f64;
    RobotSample {
        env,
        pos: [-1.0 + 0.01 * t, 0.03, -0.2 + 0.1 * env as f64],
        euler: [0.05 * (0.3 * t).sin(), 0.1 * t, 0.0],
        sin_pitch: (0.05 * (0.3 * t).sin()).sin(),
        reward: 0.01,
        episode_end: false,
        target: None,
    }
}

#[test]
fn synthetic_ticks_round_trip_with_their_entities_and_ticks() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("nested/run.rrd");
    let envs = 3;
    let options = RecordOptions { every: 3, trail: 4 };
    let mut rec = Recording::create(&path, "test", &config(envs), &options).expect("create");
    for tick in 0..=10u64 {
        let mut robots: Vec<RobotSample> = (0..envs).map(|e| robot(e, tick)).collect();
        robots[1].episode_end = tick == 4;
        // An env the config does not have is left out.
        robots.push(robot(envs, tick));
        assert_eq!(rec.robots(tick, &robots).expect("robots"), tick % 3 == 0);
        let estimates: Vec<EstimateSample> = (0..envs)
            .map(|env| EstimateSample {
                env,
                class: (tick >= 5).then_some(u8::from(env == 2)),
                posterior: if tick >= 5 { 0.9 } else { 0.0 },
                window_std: 0.01,
            })
            .collect();
        rec.estimates(tick, &estimates).expect("estimates");
    }
    let summary = rec.finish().expect("finish");
    assert_eq!((summary.robot_ticks, summary.estimate_ticks), (4, 4));
    assert_eq!(summary.bytes, std::fs::metadata(&path).expect("file").len());

    let d = Decoded::read(&path);
    let mut statics = vec![entity::WORLD.to_string(), entity::TERRAIN.to_string()];
    for env in 0..envs {
        statics.extend([entity::robot(env), entity::body(env), entity::trail(env)]);
    }
    statics.extend(entity::METRICS.map(String::from));
    assert_eq!(d.statics, statics.into_iter().collect(), "static entities");

    let logged = vec![0, 3, 6, 9];
    let mut temporal = vec![];
    for env in 0..envs {
        temporal.extend([entity::robot(env), entity::trail(env)]);
    }
    temporal.extend(entity::METRICS.map(String::from));
    assert_eq!(
        d.ticks.keys().cloned().collect::<BTreeSet<_>>(),
        temporal.iter().cloned().collect(),
        "no targets: these samples carry none"
    );
    for e in &temporal {
        assert_eq!(d.ticks_of(e), logged, "{e}");
        assert_eq!(d.rows[e], logged.len(), "one row per logged tick: {e}");
    }
}

#[test]
fn a_telemetry_csv_converts_with_its_targets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv_path = dir.path().join("telemetry.csv");
    let mut w = csv::Writer::from_path(&csv_path).expect("csv");
    for tick in 0..25u64 {
        for env in 0..2u32 {
            let target = if env == 0 && tick >= 12 { 1.0 } else { 0.5 };
            w.serialize(common::TelemetryRow {
                env,
                tick,
                x: 0.01 * tick as f64,
                z: f64::from(env),
                theta_x: 0.02,
                sin_pitch: 0.02f64.sin(),
                reward: 0.1,
                truncated: tick == 7,
                target_x: target,
                target_z: target,
                ..Default::default()
            })
            .expect("row");
        }
    }
    w.flush().expect("flush");
    drop(w);
    let config_path = dir.path().join("config.toml");
    std::fs::write(&config_path, config(2).to_toml()).expect("config");
    let out = dir.path().join("run.rrd");
    let mut args: Vec<std::ffi::OsString> = ["recorder-proc", "convert", "--every", "5"]
        .map(Into::into)
        .into();
    for (flag, path) in [
        ("--config", &config_path),
        ("--telemetry", &csv_path),
        ("--out", &out),
    ] {
        args.extend([flag.into(), path.into()]);
    }
    let code = recorder_proc::main_with_args(args);
    assert_eq!(code, std::process::ExitCode::SUCCESS);

    let d = Decoded::read(&out);
    for env in 0..2 {
        assert_eq!(d.ticks_of(&entity::robot(env)), [0, 5, 10, 15, 20]);
    }
    assert_eq!(d.ticks_of(entity::SIN_PITCH), [0, 5, 10, 15, 20]);
    // A target is logged when it changes: env 0's moved at tick 12, first logged at 15.
    assert_eq!(d.ticks_of(&entity::target(0)), [0, 15]);
    assert_eq!(d.ticks_of(&entity::target(1)), [0]);
    // The CSV has nothing of the estimator.
    assert!(d.ticks_of(entity::CLASS).is_empty());
}

#[test]
fn a_missing_csv_is_a_one_line_user_error_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("run.rrd");
    let e = convert::convert(
        &config(1),
        &dir.path().join("absent.csv"),
        &out,
        &RecordOptions::default(),
    )
    .expect_err("no such file");
    assert!(e.is_user_error());
    assert!(e.to_string().contains("absent.csv"), "{e}");
    assert!(!e.to_string().contains('\n'));
    assert!(!out.exists());
}

#[test]
fn serve_records_a_run_until_its_stop_request_and_closes_the_file() {
    use common::ipc::{self, Bus};
    use common::wire::{EnvTick, TerrainEstimate, TerrainHeader, TickHeader};

    let run = format!("rec{}", std::process::id());
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("run.rrd");
    let envs = 2;
    let cfg = config(envs);
    let bus = Bus::connect(&run, "test").expect("node");
    let control = bus.control_notifier().expect("control");
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let recorder = {
        let (run, out) = (run.clone(), out.clone());
        std::thread::spawn(move || {
            let options = RecordOptions { every: 2, trail: 8 };
            let serve = serve::Serve::connect(&cfg, &run, &out, &options)?;
            ready_tx.send(()).ok();
            serve.run()
        })
    };
    ready_rx
        .recv_timeout(std::time::Duration::from_secs(30))
        .expect("the recorder joins the run");
    let telemetry = bus
        .sender::<EnvTick, TickHeader>(&ipc::TELEMETRY, None, envs)
        .expect("telemetry");
    let terrain = bus
        .sender::<TerrainEstimate, TerrainHeader>(&ipc::TERRAIN, None, envs)
        .expect("terrain");
    for tick in 0..10u64 {
        let ticks: Vec<EnvTick> = (0..envs as u32)
            .map(|env| EnvTick {
                env,
                pos: [0.01 * tick as f32, 0.03, env as f32],
                ..Default::default()
            })
            .collect();
        let header = TickHeader {
            tick,
            envs: envs as u32,
            ..Default::default()
        };
        telemetry.send(header, &ticks).expect("send telemetry");
    }
    // Fewer estimates than the terrain service buffers, so none is overwritten unread.
    for tick in [0u64, 2, 4] {
        let estimates: Vec<TerrainEstimate> = (0..envs as u32)
            .map(|env| TerrainEstimate {
                env,
                class: common::wire::CLASS_UNKNOWN,
                ..Default::default()
            })
            .collect();
        let header = TerrainHeader {
            tick,
            envs: envs as u32,
            ..Default::default()
        };
        terrain.send(header, &estimates).expect("send estimates");
    }
    ipc::request_shutdown(&control).expect("stop");
    let summary = recorder
        .join()
        .expect("the recorder thread ends")
        .expect("the recording finishes");
    assert_eq!((summary.robot_ticks, summary.estimate_ticks), (5, 3));
    drop((telemetry, terrain, control, bus));
    ipc::remove_run(&run).expect("clean");

    let d = Decoded::read(&out);
    for env in 0..envs {
        assert_eq!(d.ticks_of(&entity::robot(env)), [0, 2, 4, 6, 8]);
        // The telemetry carries each env's target: logged once, as it never moves here.
        assert_eq!(d.ticks_of(&entity::target(env)), [0]);
    }
    assert_eq!(d.ticks_of(entity::CLASS), [0, 2, 4]);
}
