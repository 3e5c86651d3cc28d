//! `lavatube status`: runs that have shared-memory resources, their processes, and on a
//! learner host the sim hosts its bridge hears (DESIGN §9).

use common::ipc::{self, Bus};
use common::wire::SimHost;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// The learner-host bridge's node that publishes `hosts`.
const HOSTS_NODE: &str = "bridge-rollouts";
/// How long to wait for the sim-host table (the bridge publishes it every second).
const HOSTS_WAIT: Duration = Duration::from_millis(1500);

pub fn status() -> anyhow::Result<ExitCode> {
    let runs = ipc::runs_with_files();
    if runs.is_empty() {
        println!("no runs have shared-memory resources");
    }
    for run in runs {
        let nodes = ipc::list_nodes(&run)?;
        let files = ipc::run_files(&run).len();
        let alive = nodes.iter().filter(|n| n.alive).count();
        println!("run {run}: {alive} live process(es), {files} file(s)");
        for n in &nodes {
            println!(
                "  {:<16} pid {:<8} {}",
                n.name,
                n.pid,
                if n.alive { "alive" } else { "dead" }
            );
        }
        if nodes.iter().any(|n| n.alive && n.name == HOSTS_NODE) {
            print_sim_hosts(&run)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The table the learner host's bridge publishes, one line per sim host.
fn print_sim_hosts(run: &str) -> anyhow::Result<()> {
    let bus = Bus::connect(run, "status")?;
    let rx = bus.receiver(&ipc::HOSTS, None)?;
    let started = Instant::now();
    let table: Option<Vec<SimHost>> = loop {
        if let Some(s) = rx.latest()? {
            break Some(s.payload().to_vec());
        }
        if started.elapsed() > HOSTS_WAIT {
            break None;
        }
        rx.wait(Duration::from_millis(100))?;
    };
    let Some(table) = table else {
        println!("  sim hosts: no report from the bridge within {HOSTS_WAIT:?}");
        return Ok(());
    };
    println!("  sim hosts: {}", table.len());
    for h in table {
        println!(
            "    source {:<5} {:<6} {:>8} chunks (last {}), {:>10} env steps, {:>7.0} steps/s, {:>6.2} MB/s, {} lost",
            h.source,
            if h.joined != 0 { "joined" } else { "gone" },
            h.chunks,
            h.last_chunk,
            h.env_steps,
            h.steps_per_s,
            h.bytes_per_s / 1e6,
            h.lost
        );
    }
    Ok(())
}
