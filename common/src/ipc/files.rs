//! A run's shared-memory resources as files: the nodes registered, the files left behind by
//! dead runs, and their removal.

use super::{IpcError, Svc, ipc_err, resource_prefix, run_config};
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// A node of a run, as `lavatube status` shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeInfo {
    pub name: String,
    pub pid: i32,
    pub alive: bool,
}

/// The nodes registered in run `run`, alive or dead.
pub fn list_nodes(run: &str) -> Result<Vec<NodeInfo>, IpcError> {
    let cfg = run_config(run)?;
    let mut out = Vec::new();
    Node::<Svc>::list(&cfg, |state| {
        let (view_details, alive) = match &state {
            NodeState::Alive(v) => (v.details().clone(), true),
            NodeState::Dead(v) => (v.details().clone(), false),
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => (None, false),
        };
        if let Some(d) = view_details {
            out.push(NodeInfo {
                name: d.name().to_string(),
                pid: d.process_id().value(),
                alive,
            });
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc_err(format!("list nodes of run `{run}`"))(&e))?;
    Ok(out)
}

/// Directories where iceoryx2 keeps files: the shared-memory mount and its root path.
fn resource_dirs() -> Vec<std::path::PathBuf> {
    let root = iceoryx2::config::Config::default()
        .global
        .root_path()
        .to_string();
    vec![
        std::path::PathBuf::from("/dev/shm"),
        std::path::PathBuf::from(root),
    ]
}

fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// Every file of run `run` in the shared-memory mount and iceoryx2's root path.
pub fn run_files(run: &str) -> Vec<std::path::PathBuf> {
    let prefix = resource_prefix(run);
    let mut all = Vec::new();
    for d in resource_dirs() {
        walk(&d, &mut all);
    }
    all.retain(|p| {
        p.file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with(&prefix))
    });
    all
}

/// Run ids that have files left, from their file names.
pub fn runs_with_files() -> Vec<String> {
    let mut all = Vec::new();
    for d in resource_dirs() {
        walk(&d, &mut all);
    }
    let mut runs: Vec<String> = all
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            let rest = name.strip_prefix("lavatube_")?;
            Some(rest.split('_').next()?.to_string())
        })
        .collect();
    runs.sort();
    runs.dedup();
    runs
}

/// Removes run `run`'s shared-memory resources: dead nodes' through iceoryx2, then any file
/// left with the run's prefix. Refuses while a node of the run is alive. Returns the number
/// of files removed.
pub fn remove_run(run: &str) -> Result<usize, IpcError> {
    let cfg = run_config(run)?;
    let nodes = list_nodes(run)?;
    if let Some(n) = nodes.iter().find(|n| n.alive) {
        return Err(IpcError {
            what: format!("clean run `{run}`"),
            reason: format!("node `{}` (pid {}) is still alive", n.name, n.pid),
        });
    }
    Node::<Svc>::list(&cfg, |state| {
        if let NodeState::Dead(v) = state {
            let _ = v.try_remove_stale_resources();
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc_err(format!("list nodes of run `{run}`"))(&e))?;
    let files = run_files(run);
    let mut removed = 0;
    for f in &files {
        if std::fs::remove_file(f).is_ok() {
            removed += 1;
        }
    }
    Ok(removed)
}
