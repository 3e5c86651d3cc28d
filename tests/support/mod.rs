//! Shared by the end-to-end tests: running the launcher as a real process, with a watchdog
//! instead of a timing assertion.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Kills the launcher if it has not finished in time.
const WATCHDOG: Duration = Duration::from_secs(900);

/// The repository root: configs and run directories are relative to it.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `lavatube run --config CONFIG --run-id RUN_ID --quiet` from the repository root, to the
/// end. Returns the exit code and everything it printed (captured in a file, so a chatty
/// run cannot block on a full pipe).
pub fn lavatube_run(config: &str, run_id: &str) -> (i32, String) {
    let log_path = std::env::temp_dir().join(format!("lavatube-test-{run_id}.log"));
    let log = std::fs::File::create(&log_path).expect("log file");
    let mut child = Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(["run", "--config", config, "--run-id", run_id, "--quiet"])
        .current_dir(root())
        .stdout(Stdio::from(log.try_clone().expect("log file")))
        .stderr(Stdio::from(log))
        .spawn()
        .expect("launcher starts");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("poll") {
            break status;
        }
        if started.elapsed() > WATCHDOG {
            child.kill().expect("kill");
            panic!("lavatube run did not finish within {WATCHDOG:?}");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let text = std::fs::read_to_string(&log_path).unwrap_or_default();
    let _ = std::fs::remove_file(&log_path);
    (status.code().unwrap_or(-1), text)
}
