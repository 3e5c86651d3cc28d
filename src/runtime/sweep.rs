//! Removing what dead runs left in shared memory. A launcher killed with SIGKILL cannot clean
//! up; its children stop by themselves (see [`Child`](super::Child)), and the next launcher
//! command removes the run's files.

use common::ipc;
use std::path::Path;
use std::time::{Duration, SystemTime};

/// How old the files of a run with no node must be before they count as left behind. A
/// starting run registers its first node within milliseconds of its first file; a run whose
/// last node went away in the middle of its cleanup leaves files and no node.
const ORPHAN_AGE: Duration = Duration::from_secs(60);

/// Removes the shared-memory files of every run whose registered nodes are all dead, and of
/// every run with no node whose files are all older than [`ORPHAN_AGE`] (a younger one may
/// be starting). Returns `(run id, files removed)` for each run swept.
pub fn sweep_dead_runs() -> Vec<(String, usize)> {
    let mut swept = Vec::new();
    for run in ipc::runs_with_files() {
        let Ok(nodes) = ipc::list_nodes(&run) else {
            continue;
        };
        if nodes.iter().any(|n| n.alive) {
            continue;
        }
        if nodes.is_empty()
            && !ipc::run_files(&run)
                .iter()
                .all(|f| older_than(f, ORPHAN_AGE))
        {
            continue;
        }
        if let Ok(n) = ipc::remove_run(&run) {
            swept.push((run, n));
        }
    }
    swept
}

fn older_than(file: &Path, age: Duration) -> bool {
    std::fs::metadata(file)
        .and_then(|m| m.modified())
        .is_ok_and(|t| SystemTime::now().duration_since(t).is_ok_and(|d| d >= age))
}

/// Sweeps (see [`sweep_dead_runs`]) and says what was removed, one line per run.
pub fn report_sweep() {
    for (run, files) in sweep_dead_runs() {
        eprintln!("lavatube: removed {files} file(s) left by dead run {run}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file named as run `run`'s, modified `age` ago.
    fn stray_file(run: &str, age: Duration) -> std::path::PathBuf {
        let path = Path::new("/dev/shm").join(format!("{}stray", ipc::resource_prefix(run)));
        let f = std::fs::File::create(&path).expect("a file in /dev/shm");
        f.set_modified(SystemTime::now() - age).expect("set mtime");
        path
    }

    #[test]
    fn files_without_a_node_are_swept_once_they_are_old() {
        let pid = std::process::id();
        let (old, young) = (format!("sweep-old-{pid}"), format!("sweep-young-{pid}"));
        let old_file = stray_file(&old, 2 * ORPHAN_AGE);
        let young_file = stray_file(&young, Duration::ZERO);
        let swept = sweep_dead_runs();
        let young_left = young_file.exists();
        let _ = std::fs::remove_file(&young_file);
        assert!(swept.contains(&(old.clone(), 1)), "{swept:?}");
        assert!(!old_file.exists(), "the old file is removed");
        assert!(young_left, "a run that may be starting is left alone");
        assert!(!swept.iter().any(|(r, _)| *r == young), "{swept:?}");
    }
}
