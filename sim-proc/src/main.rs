use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    common::logging::init();
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
