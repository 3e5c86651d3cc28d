//! `lavatube bench`: where time goes, stage by stage, in one invocation. For each
//! env count and sim thread count it runs, on the same rough-ground envs and seed:
//! a. physics alone, b. + policy inference, c. + publishing through iceoryx2 to a reader
//! process, d. + the learner in sync mode, e. + the learner in async mode, f. + the estimator;
//! then the same bytes over iceoryx2 and over a Unix socket between two processes, and
//! rollout chunks and policies through a pair of Zenoh bridges on loopback. It prints the
//! tables and writes `bench.json`.
//!
//! Every stage runs the real binaries with the arguments `lavatube run` gives them, so the
//! numbers are the runtime's own. The launcher only starts, watches and stops them.

mod bridge;
mod config;
mod files;
mod reader;
mod report;
mod stages;
mod transport;

pub use config::Plan;
pub use reader::{ReaderArgs, reader};
pub use transport::{EchoArgs, echo};

use super::UserError;
use crate::runtime;
use anyhow::Context;
use common::ipc::{self, Bus};
use config::Measurement;
use indicatif::{ProgressBar, ProgressStyle};
use stages::Interrupted;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use transport::{Kind, Payload};

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Bench file (TOML): a `[bench]` table naming the env counts, thread counts, budgets and
    /// the runtime config. Default: the built-in defaults (`configs/bench.toml` spells them
    /// out, with `configs/default.toml` as the runtime).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also write the results (JSON) here; they always go to `<out-dir>/<bench-id>/bench.json`.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// A few hundred env steps per measurement and a small rollout: checks the tool and its
    /// output in seconds; the numbers are not for quoting.
    #[arg(long)]
    pub quick: bool,
    /// Measure only rollout chunks and policies through the Zenoh bridge (DESIGN §9), with
    /// the runtime config's chunk and policy sizes; no stages, no transport comparison.
    #[arg(long)]
    pub bridge_only: bool,
}

/// Messages per kind and phase through the bridge: each chunk is a quarter megabyte.
const BRIDGE_MESSAGES: usize = 1000;

pub fn bench(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let plan = Plan::load(args.config.as_deref(), args.quick)?;
    check_json_dir(args.json.as_deref())?;
    let bins = runtime::Binaries::locate()?;
    runtime::report_sweep();
    let (bench_id, dir) = bench_dir(&plan)?;
    let mut machine = report::Machine::now();
    let policy = stages::RandomPolicy::write(&plan.runtime, &dir)?;

    let (measurements, payloads) = if args.bridge_only {
        (Vec::new(), Vec::new())
    } else {
        (plan.measurements(), payloads(&plan, policy.weights.len()))
    };
    let bar = progress_bar((measurements.len() + payloads.len()) as u64);
    runtime::say(
        &bar,
        format!(
            "bench {bench_id}: {} measurements and {} payloads → {}",
            measurements.len(),
            payloads.len(),
            dir.display()
        ),
    );

    // The bench's own node: the transport comparison's run, and from its creation on, Ctrl-C
    // is a request the bench sees (see `Ctx::check_interrupt`) rather than its death.
    let home = Bus::connect(&bench_id, "bench")?;
    let ctx = stages::Ctx {
        plan: &plan,
        bins: &bins,
        dir: &dir,
        bench_id: &bench_id,
        home: &home,
        policy: &policy,
    };
    let outcome = measure_all(&ctx, &bar, &measurements, &payloads);
    bar.finish_and_clear();
    drop(home);
    if let Err(e) = ipc::remove_run(&bench_id) {
        eprintln!("lavatube: {e}");
    }
    let Measured {
        rows,
        transport,
        bridged,
    } = match outcome {
        Ok(measured) => measured,
        Err(e) if e.is::<Interrupted>() => {
            eprintln!(
                "lavatube: bench interrupted; partial logs in {}",
                dir.display()
            );
            return Ok(ExitCode::from(130));
        }
        Err(e) => return Err(e.context(format!("logs in {}", dir.display()))),
    };

    machine.load_1m_end = report::load_1m();
    let report = report::Report::new(
        &plan,
        bench_id,
        machine,
        policy.weights.len(),
        rows,
        transport,
        bridged,
    );
    print!("{}", report.text());
    write_results(&report, &dir, args.json.as_deref())?;
    Ok(ExitCode::SUCCESS)
}

/// Refuses `--json` in a directory that does not exist, before anything runs.
fn check_json_dir(json: Option<&Path>) -> anyhow::Result<()> {
    if let Some(parent) = json.and_then(Path::parent)
        && !parent.as_os_str().is_empty()
        && !parent.is_dir()
    {
        return Err(UserError(format!(
            "--json: directory {} does not exist",
            parent.display()
        ))
        .into());
    }
    Ok(())
}

/// A new bench id, from the time and this process, and its directory under `bench.out-dir`.
fn bench_dir(plan: &Plan) -> anyhow::Result<(String, PathBuf)> {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let bench_id = format!("b{secs:x}-{:x}", std::process::id());
    let dir = std::path::absolute(plan.bench.out_dir.join(&bench_id))
        .with_context(|| format!("cannot resolve {}", plan.bench.out_dir.display()))?;
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok((bench_id, dir))
}

/// The bench's progress bar over `len` steps, ticking on its own.
fn progress_bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

/// Everything the bench measured.
struct Measured {
    rows: Vec<stages::Row>,
    transport: Vec<transport::TransportRow>,
    bridged: (bridge::Bridged, bridge::SimRates),
}

/// Measures in order: every stage measurement, the transport comparison of `payloads`, the
/// Zenoh bridge, and a sim behind the bridge.
fn measure_all(
    ctx: &stages::Ctx,
    bar: &ProgressBar,
    measurements: &[Measurement],
    payloads: &[Payload],
) -> anyhow::Result<Measured> {
    let (plan, bins, dir, bench_id) = (ctx.plan, ctx.bins, ctx.dir, ctx.bench_id);
    let rows = measure_stages(ctx, bar, measurements)?;
    bar.set_message("the same bytes over iceoryx2 and a Unix socket");
    let transport = if payloads.is_empty() {
        Vec::new()
    } else {
        transport::compare(
            ctx.home,
            &bins.launcher,
            dir,
            payloads,
            plan.bench.transport_messages,
            &ctx.policy.weights,
            &mut |p| {
                bar.inc(1);
                bar.set_message(format!("transport: {} done", p.label()));
            },
        )
        .context("transport comparison")?
    };
    bar.set_message("rollout chunks and policies through the Zenoh bridge");
    let bridged = bridge::measure(
        &plan.runtime,
        bins,
        dir,
        bench_id,
        &ctx.policy.weights,
        plan.bench.transport_messages.min(BRIDGE_MESSAGES),
    )
    .context("bridge")?;
    bar.set_message("one sim behind the bridge against the same sim on one host");
    let sim = bridge::sim_rates(
        &plan.runtime,
        &bins.launcher,
        dir,
        bench_id,
        plan.bench.env_steps,
    )
    .context("a sim behind the bridge")?;
    Ok(Measured {
        rows,
        transport,
        bridged: (bridged, sim),
    })
}

/// Runs every stage measurement in order, each row's numbers shown as it is done.
fn measure_stages(
    ctx: &stages::Ctx,
    bar: &ProgressBar,
    measurements: &[Measurement],
) -> anyhow::Result<Vec<stages::Row>> {
    let mut rows = Vec::new();
    for m in measurements {
        bar.set_message(format!(
            "{} {} · {} envs · {} thread(s)",
            m.stage.letter(),
            m.stage.name(),
            m.envs,
            m.threads
        ));
        let row = stages::measure(ctx, m)
            .with_context(|| format!("stage {} ({})", m.stage.letter(), m.label()))?;
        runtime::say(
            bar,
            format!(
                "{:<26} {:>9.0} decision steps/s{}",
                format!(
                    "{} {} N={} t={}",
                    row.stage, row.stage_name, row.envs, row.threads
                ),
                row.decision_steps_per_s,
                row.transport_latency_p50_us
                    .map_or(String::new(), |l| format!(", tick latency p50 {l:.1} µs")),
            ),
        );
        rows.push(row);
        bar.inc(1);
    }
    Ok(rows)
}

/// Writes the report as `bench.json` in the bench directory, and to `json` when given, and
/// says where.
fn write_results(report: &report::Report, dir: &Path, json: Option<&Path>) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(report)?;
    let path = dir.join("bench.json");
    std::fs::write(&path, &text).with_context(|| format!("cannot write {}", path.display()))?;
    if let Some(out) = json {
        std::fs::write(out, &text).with_context(|| format!("cannot write {}", out.display()))?;
    }
    println!(
        "results: {}{}",
        path.display(),
        json.map_or(String::new(), |o| format!(" and {}", o.display()))
    );
    Ok(())
}

/// The transport comparison's payloads: a telemetry tick and a rollout chunk per env count,
/// and the policy's weights.
fn payloads(plan: &Plan, policy_len: usize) -> Vec<Payload> {
    let mut out = Vec::new();
    for &n in &plan.bench.envs {
        out.push(Payload {
            kind: Kind::Telemetry,
            envs: Some(n),
            elements: n,
        });
    }
    for &n in &plan.bench.envs {
        let t = plan.rollout_steps(n) as usize;
        out.push(Payload {
            kind: Kind::Rollout,
            envs: Some(n),
            elements: t * n + n,
        });
    }
    out.push(Payload {
        kind: Kind::Weights,
        envs: None,
        elements: policy_len,
    });
    out
}
