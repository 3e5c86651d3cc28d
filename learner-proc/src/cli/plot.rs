//! `learner-proc plot --metrics RUN_DIR/metrics.csv --out FILE.png`: a run's learning curves,
//! during the run or after it (`serve` keeps `<run-dir>/curves.png` current at checkpoints).

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::{LearnerError, curves};

#[derive(Debug, Args)]
pub struct PlotArgs {
    /// A run's metrics CSV (`<run-dir>/metrics.csv`); it may still be growing.
    #[arg(long)]
    pub metrics: PathBuf,
    /// The PNG to write; an existing file is replaced atomically.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn plot(args: &PlotArgs, out: &mut dyn Write) -> Result<(), LearnerError> {
    let updates = curves::plot(&args.metrics, &args.out)?;
    writeln!(
        out,
        "wrote {} ({})",
        args.out.display(),
        curves::updates(updates)
    )
    .map_err(LearnerError::io(
        "writing the report to",
        Path::new("<stdout>"),
    ))
}
