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
