use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match sim_proc::run(sim_proc::Args::parse()) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("sim-proc: {e:#}");
            ExitCode::from(if e.downcast_ref::<common::ConfigError>().is_some() {
                1
            } else {
                2
            })
        }
    }
}
