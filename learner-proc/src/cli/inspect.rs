//! `learner-proc inspect PATH`: what a checkpoint holds, without loading a learner.

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::LearnerError;
use crate::checkpoint::{self, FORMAT_VERSION};

#[derive(Debug, Args)]
pub struct InspectArgs {
    /// A checkpoint file, or a checkpoint directory (then its newest intact checkpoint, after
    /// listing the newer ones that are corrupt).
    pub path: PathBuf,
}

pub fn inspect(args: &InspectArgs, out: &mut dyn Write) -> Result<(), LearnerError> {
    let (ckpt, path, skipped) = if args.path.is_dir() {
        checkpoint::load_latest_good(&args.path)?
    } else {
        (checkpoint::read(&args.path)?, args.path.clone(), Vec::new())
    };
    let mut report = String::new();
    for e in &skipped {
        report += &format!("skipped          {e}\n");
    }
    report += &format!(
        "checkpoint       {} (format {FORMAT_VERSION})\n\
         update           {}\n\
         global step      {}\n\
         policy version   {}\n\
         learning rate    {:e} (next update)\n\
         actor            {} tanh, {} parameters with the log-std, {} in all with the critic\n\
         adam step        {}\n\
         obs-norm count   {}\n",
        path.display(),
        ckpt.counters.update,
        ckpt.counters.global_step,
        ckpt.counters.policy_version,
        ckpt.learning_rate,
        checkpoint::widths(&ckpt.layout),
        ckpt.layout.len() - 2 * ckpt.layout.obs_dim,
        ckpt.params.len(),
        ckpt.adam.step,
        ckpt.obs_norm.count,
    );
    out.write_all(report.as_bytes()).map_err(LearnerError::io(
        "writing the report to",
        Path::new("<stdout>"),
    ))
}
