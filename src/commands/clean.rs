//! `lavatube clean`: remove the shared-memory resources of runs with no live process.

use super::UserError;
use std::process::ExitCode;

pub fn clean(only: Option<&str>) -> anyhow::Result<ExitCode> {
    if let Some(run) = only {
        common::ipc::validate_run_id(run).map_err(UserError)?;
    }
    let runs: Vec<String> = match only {
        Some(run) => vec![run.to_string()],
        None => common::ipc::runs_with_files(),
    };
    let mut busy = false;
    for run in runs {
        match common::ipc::remove_run(&run) {
            Ok(n) => println!("run {run}: removed {n} file(s)"),
            Err(e) => {
                busy = true;
                println!("run {run}: kept ({e})");
            }
        }
    }
    Ok(if busy {
        ExitCode::from(super::EXIT_USER)
    } else {
        ExitCode::SUCCESS
    })
}
