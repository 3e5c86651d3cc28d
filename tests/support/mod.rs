//! Shared by the end-to-end tests: running the launcher as a real process.

use std::path::Path;
use std::process::{Command, Output};

/// The repository root: configs and run directories are relative to it.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `lavatube run --config CONFIG --run-id RUN_ID --quiet` from the repository root, to the end;
/// panics with the launcher's stderr if it fails.
pub fn lavatube_run(config: &str, run_id: &str) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_lavatube"))
        .args(["run", "--config", config, "--run-id", run_id, "--quiet"])
        .current_dir(root())
        .output()
        .expect("launcher runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}
