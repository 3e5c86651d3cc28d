//! Removing what dead runs left in shared memory. A launcher killed with SIGKILL cannot clean
//! up; its children stop by themselves (see [`Child`](super::Child)), and the next launcher
//! command removes the run's files.

use common::ipc;

/// Removes the shared-memory files of every run whose registered nodes are all dead (a run
/// with no node yet, or one whose nodes are still being created, is left alone: it may be
/// starting). Returns `(run id, files removed)` for each run swept.
pub fn sweep_dead_runs() -> Vec<(String, usize)> {
    let mut swept = Vec::new();
    for run in ipc::runs_with_files() {
        let Ok(nodes) = ipc::list_nodes(&run) else {
            continue;
        };
        if nodes.is_empty() || nodes.iter().any(|n| n.alive) {
            continue;
        }
        if let Ok(n) = ipc::remove_run(&run) {
            swept.push((run, n));
        }
    }
    swept
}

/// Sweeps (see [`sweep_dead_runs`]) and says what was removed, one line per run.
pub fn report_sweep() {
    for (run, files) in sweep_dead_runs() {
        eprintln!("lavatube: removed {files} file(s) left by dead run {run}");
    }
}
