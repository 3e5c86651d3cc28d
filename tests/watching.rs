//! What a person sees of a run, checked from the outside: a terminal of a few readable lines
//! (no child INFO line), the map of the world, and TensorBoard event files per learner and
//! for the launcher.

mod support;

use common::Config;
use common::map::Map;
use common::terrain::Terrain;

/// Event files directly in `dir`.
fn event_files(dir: &std::path::Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |d| {
        d.filter_map(Result::ok)
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with("events.out.tfevents.")
            })
            .count()
    })
}

#[test]
fn a_run_off_a_terminal_prints_a_few_lines_and_leaves_a_map_and_events() {
    let run_id = format!("watch-{}", std::process::id());
    let args = ["--config", "configs/smoke.toml", "--run-id", &run_id];
    let (code, output) = support::Launched::shown(&args, &run_id).wait();
    assert_eq!(code, 0, "launcher output:\n{output}");
    let lines: Vec<&str> = output.lines().collect();
    // The start line, one summary line (the smoke run is shorter than `run.summary-every`),
    // the end line; nothing from the children's routine logs.
    assert!(lines.len() <= 6, "{} lines:\n{output}", lines.len());
    assert!(!output.contains(" INFO "), "a child's INFO line:\n{output}");
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("general  step ") && l.contains("entropy") && l.contains("KL")),
        "a summary line:\n{output}"
    );
    let end = format!("run {run_id}: 3,072 env steps in ");
    assert!(
        lines.last().is_some_and(|l| l.starts_with(&end)),
        "{output}"
    );

    let dir = support::root().join("target/e2e-runs").join(&run_id);
    let cfg = Config::load(&support::root().join("configs/smoke.toml")).expect("config");
    let terrain = Terrain::build(&cfg.sim.terrain).expect("terrain");
    let map = Map::of(&terrain);
    let png = std::fs::File::open(dir.join("map.png")).expect("map.png");
    let info = png::Decoder::new(std::io::BufReader::new(png))
        .read_info()
        .expect("a PNG")
        .info()
        .clone();
    assert_eq!(
        (info.width as usize, info.height as usize),
        (map.width, map.height),
        "the map has the terrain's size"
    );
    assert!(
        event_files(&dir) >= 1,
        "the learner's events beside metrics.csv"
    );
    assert!(
        event_files(&dir.join("launcher")) >= 1,
        "the launcher's events"
    );
}

#[test]
fn a_recorded_run_leaves_an_rrd_and_survives_its_recorders_death() {
    let run_id = format!("record-{}", std::process::id());
    let base = std::fs::read_to_string(support::root().join("configs/smoke.toml")).expect("smoke");
    // Long enough to kill the recorder mid-run; recorded to the run directory.
    let text = base.replace(
        "total-steps = 3072",
        "total-steps = 30_720\nrecord = \"run.rrd\"",
    );
    let config = support::root()
        .join("target/e2e-runs")
        .join(format!("{run_id}.toml"));
    std::fs::create_dir_all(config.parent().expect("dir")).expect("dir");
    std::fs::write(&config, text).expect("config");
    let config = config.display().to_string();
    let launched = support::Launched::start(&config, &run_id);

    let dir = support::root().join("target/e2e-runs").join(&run_id);
    let recording = dir.join("run.rrd");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let recorder = loop {
        let node = common::ipc::list_nodes(&run_id)
            .unwrap_or_default()
            .into_iter()
            .find(|n| n.alive && n.name == "recorder");
        if let Some(n) = node
            && recording.metadata().is_ok_and(|m| m.len() > 0)
        {
            break n.pid;
        }
        assert!(std::time::Instant::now() < deadline, "no recorder");
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    // SAFETY: kill(2) on the recorder the launcher started for this test's run.
    unsafe {
        libc::kill(recorder as i32, libc::SIGKILL);
    }
    let (code, output) = launched.wait();
    assert_eq!(code, 0, "the run goes on without its recorder:\n{output}");
    assert!(
        output.contains("recorder exited with signal: 9"),
        "{output}"
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("summary.json")).expect("summary.json"),
    )
    .expect("json");
    assert_eq!(summary["env_steps"].as_u64(), Some(30_720), "{summary}");
    assert_eq!(
        summary["restarts"]["recorder"].as_u64(),
        Some(0),
        "{summary}"
    );
}
