//! `estimator-proc online TRACES.csv [--windows …] [--splice] [--hold N] [--out DIR]`: the online
//! estimator replayed on a recording, per window size.

use super::input::{InputArgs, Resolved};
use crate::report::{OnlineReport, create_dir, print_output, to_json, write_file};
use crate::{analysis, evaluation, traces};
use anyhow::Context as _;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct OnlineArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Splice the series into streams that alternate flat and rough, to create terrain changes
    /// in recordings where no env changes area (as the paper's).
    #[arg(long)]
    pub splice: bool,
    /// A change counts as detected once the class stays on the new area for this many ticks.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub hold: u32,
    /// Also write online.json and online.md into this directory (created if missing).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn execute(args: &OnlineArgs) -> anyhow::Result<()> {
    let Resolved {
        est: cfg,
        seed,
        min_step_travel,
        ..
    } = args.input.resolve()?;
    let path = &args.input.traces;
    let rows = traces::read_telemetry(path, cfg.signal)?;
    let series = analysis::split_series(&rows, cfg.warmup_ticks);
    let hold = args.hold as usize;
    let windows = cfg
        .windows
        .iter()
        .map(|&w| {
            evaluation::evaluate_online(&series, &cfg, w, seed, args.splice, hold, min_step_travel)
                .with_context(|| format!("window {w}"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let report = OnlineReport {
        input: path.display().to_string(),
        splice: args.splice,
        hold,
        seed,
        windows,
    };
    let markdown = report.to_markdown();
    if let Some(out) = &args.out {
        create_dir(out)?;
        write_file(&out.join("online.json"), &to_json(&report))?;
        write_file(&out.join("online.md"), &markdown)?;
    }
    print_output(&markdown);
    Ok(())
}
