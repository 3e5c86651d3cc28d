//! `lavatube status`: runs that have shared-memory resources, and their processes.

use std::process::ExitCode;

pub fn status() -> anyhow::Result<ExitCode> {
    let runs = common::ipc::runs_with_files();
    if runs.is_empty() {
        println!("no runs have shared-memory resources");
    }
    for run in runs {
        let nodes = common::ipc::list_nodes(&run)?;
        let files = common::ipc::run_files(&run).len();
        let alive = nodes.iter().filter(|n| n.alive).count();
        println!("run {run}: {alive} live process(es), {files} file(s)");
        for n in nodes {
            println!(
                "  {:<10} pid {:<8} {}",
                n.name,
                n.pid,
                if n.alive { "alive" } else { "dead" }
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
