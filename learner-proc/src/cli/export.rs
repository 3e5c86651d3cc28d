//! `learner-proc export CHECKPOINT --out FILE.policy`: a checkpoint's actor (with its
//! observation normalisation) as a `.policy` file, for `sim-proc --controller policy` and for
//! evaluations that need no learner.

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::LearnerError;
use crate::checkpoint::{self, write_atomic};

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// A checkpoint file, or a checkpoint directory (its newest intact checkpoint).
    pub checkpoint: PathBuf,
    /// The policy file to write (atomically).
    #[arg(long)]
    pub out: PathBuf,
    /// Clip of normalised observations the policy applies (`ppo.obs-clip`).
    #[arg(long, default_value_t = 10.0)]
    pub obs_clip: f32,
}

pub fn export(args: &ExportArgs, out: &mut dyn Write) -> Result<(), LearnerError> {
    let (ckpt, path) = if args.checkpoint.is_dir() {
        let (ckpt, path, _) = checkpoint::load_latest_good(&args.checkpoint)?;
        (ckpt, path)
    } else {
        (checkpoint::read(&args.checkpoint)?, args.checkpoint.clone())
    };
    let policy = ckpt.policy(args.obs_clip)?;
    write_atomic(&args.out, &policy.to_bytes())?;
    writeln!(
        out,
        "wrote {} ({} actor, policy version {}, from {})",
        args.out.display(),
        checkpoint::widths(&ckpt.layout),
        ckpt.counters.policy_version,
        path.display()
    )
    .map_err(LearnerError::io(
        "writing the report to",
        Path::new("<stdout>"),
    ))
}
