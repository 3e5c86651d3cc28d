//! The subcommands, one module each, thin over [`crate::runtime`].

mod analyze;
mod bench;
mod check_config;
mod clean;
mod evaluate;
mod export;
mod map;
mod reproduce;
mod run;
mod status;
mod swap;
mod world;

pub use crate::error::{EXIT_FAILURE, EXIT_USER, UserError, exit_code};
use std::process::ExitCode;

/// lavatube: train and evaluate terrain-adaptive driving policies for lava-tube robots.
#[derive(Debug, clap::Parser)]
#[command(name = "lavatube", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Train: start the simulator, learner and estimator of a new run and supervise them
    /// (with `--listen`, only the learners: sim hosts join over the network).
    Run(run::RunArgs),
    /// Be a sim host of a run across hosts: its sim, estimator and a bridge to the learner host.
    Join(run::JoinArgs),
    /// The paper's experiment end to end, stage by stage (resumable): models, Table 3, Table 1.
    Reproduce(reproduce::ReproduceArgs),
    /// Policies on named worlds (`--worlds`: nominal, slippery, heavy, latency, …): success
    /// and reach time per world and policy on the same seeded courses, a table and a chart.
    Evaluate(evaluate::EvaluateArgs),
    /// What a robot needs to drive outside lavatube: each actor as ONNX and `.policy`, rows to
    /// check a runtime against, and the control settings (`controller.toml`).
    Export(export::ExportArgs),
    /// Replace a running run's learner (new hyperparameters or checkpoint); the sim keeps going.
    SwapLearner(swap::SwapArgs),
    /// The paper's terrain analysis (SPEC S7) on recorded telemetry: Table 3 and Figs. 5–8.
    Analyze(analyze::AnalyzeArgs),
    /// Parse and validate a config file, start nothing; or explain a field, or print the
    /// reference of every field.
    CheckConfig(check_config::CheckArgs),
    /// Draw a run's map again (the world, every robot's path by the terrain it acted for, targets,
    /// successes and failures), from its run directory or a telemetry CSV.
    Map(map::MapArgs),
    /// The world a config describes, as a file: `world export --out floor.obj`.
    #[command(subcommand)]
    World(world::WorldCommand),
    /// List runs with shared-memory resources and their processes.
    Status,
    /// Measure throughput stage by stage (physics, policy, iceoryx2, learner sync and async,
    /// estimator) for several env and thread counts, and iceoryx2 against a Unix socket.
    Bench(bench::BenchArgs),
    /// The reading process of a bench stage (started by `lavatube bench`).
    #[command(hide = true)]
    BenchReader(bench::ReaderArgs),
    /// The receiving process of the bench's transport comparison (started by `lavatube bench`).
    #[command(hide = true)]
    BenchEcho(bench::EchoArgs),
    /// Remove the shared-memory resources of runs whose processes are all gone.
    Clean {
        /// Only this run.
        #[arg(long)]
        run_id: Option<String>,
    },
}

pub fn dispatch(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Run(args) => run::run(args),
        Command::Join(args) => run::join(args),
        Command::Reproduce(args) => reproduce::reproduce(args),
        Command::Evaluate(args) => evaluate::evaluate(args),
        Command::Export(args) => export::export_command(args),
        Command::SwapLearner(args) => swap::swap_learner_command(args),
        Command::Analyze(args) => analyze::analyze(args),
        Command::CheckConfig(args) => check_config::check_config(&args),
        Command::Bench(args) => bench::bench(args),
        Command::BenchReader(args) => bench::reader(args),
        Command::BenchEcho(args) => bench::echo(args),
        Command::Map(args) => map::map_command(args),
        Command::Status => status::status(),
        Command::World(command) => world::world(command),
        Command::Clean { run_id } => clean::clean(run_id.as_deref()),
    }
}
