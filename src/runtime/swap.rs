//! The launcher's side of a learner swap (DESIGN §4): check the new learner before touching
//! the old one (`learner-proc serve --check`: config, checkpoint and network shape), stop the
//! old one with SIGTERM (it checkpoints and exits), and start the new one, which resumes the
//! run's newest checkpoint (or the named one) and continues the version sequence.

use super::{Supervised, ladder};
use common::wire::SwapRequest;
use common::{Config, run_dir};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The learner's arguments: `join` (serve, config, run id), its run directory, and a
/// checkpoint to start from instead of the run's newest.
pub fn learner_args(join: &[String], dir: &Path, checkpoint: Option<&Path>) -> Vec<String> {
    let mut a = join.to_vec();
    a.extend(["--out".into(), dir.display().to_string()]);
    if let Some(c) = checkpoint {
        a.extend(["--checkpoint".into(), c.display().to_string()]);
    }
    a
}

/// Sections that differ between the running config and a new learner's, which must not: the
/// sim keeps running with the old ones, and the learner's batch shape follows from them.
fn fixed_sections_differ(running: &Config, new: &Config) -> Vec<&'static str> {
    let mut differ = Vec::new();
    if running.run != new.run {
        differ.push("[run]");
    }
    if running.sim != new.sim {
        differ.push("[sim]");
    }
    differ
}

/// What a swap needs of the run around it.
pub struct SwapContext<'a> {
    pub running: &'a Config,
    pub run_dir: &'a Path,
    pub logs: &'a Path,
    pub bar: &'a ProgressBar,
    pub grace: Duration,
}

/// Replaces the learner `learner` as `req` asks; `n` numbers the swap (for the new learner's
/// config file). Returns what happened, or why nothing did (the old learner then still runs).
pub fn swap_learner(
    learner: &mut Supervised,
    req: &SwapRequest,
    n: u32,
    ctx: &SwapContext,
) -> Result<String, String> {
    // The running learner's arguments: `serve … --out DIR [--checkpoint P]`.
    let args = &learner.spec.args;
    let Some(at) = args.iter().position(|a| a == "--out") else {
        return Err(format!(
            "{} was not started with --out",
            learner.role().name()
        ));
    };
    let out = PathBuf::from(args.get(at + 1).cloned().unwrap_or_default());
    let mut join = args[..at].to_vec();
    let config = req.config();
    if !config.is_empty() {
        let new = Config::load(Path::new(&config)).map_err(|e| e.to_string())?;
        let differ = fixed_sections_differ(ctx.running, &new);
        if !differ.is_empty() {
            return Err(format!(
                "{config} differs from the running config in {}: a new learner may change only [ppo], [estimator] and [supervise]",
                differ.join(", ")
            ));
        }
        let resolved = ctx.run_dir.join(run_dir::swapped_learner_config(n));
        std::fs::write(&resolved, new.to_toml())
            .map_err(|e| format!("cannot write {}: {e}", resolved.display()))?;
        if let Some(i) = join.iter().position(|a| a == "--config") {
            join[i + 1] = resolved.display().to_string();
        }
    }
    let checkpoint = req.checkpoint();
    let checkpoint = (!checkpoint.is_empty()).then(|| PathBuf::from(checkpoint));
    let first_args = learner_args(&join, &out, checkpoint.as_deref());
    let check = std::process::Command::new(&learner.spec.bin)
        .args(&first_args)
        .arg("--check")
        .output()
        .map_err(|e| format!("cannot run {}: {e}", learner.spec.bin.display()))?;
    let said = String::from_utf8_lossy(&check.stderr);
    let last = said.lines().last().unwrap_or("").trim().to_string();
    if !check.status.success() {
        return Err(last);
    }
    let old = learner.child.pid();
    ladder::terminate(&mut learner.child, ctx.grace);
    learner.spec.args = first_args;
    learner
        .replace(ctx.logs, ctx.bar)
        .map_err(|e| format!("{e:#}"))?;
    // Later restarts resume the run's newest checkpoint, which the new learner writes.
    learner.spec.args = learner_args(&join, &out, None);
    Ok(format!(
        "learner swapped: pid {old} -> {} ({}; {})",
        learner.child.pid(),
        if config.is_empty() {
            "same config".to_string()
        } else {
            config
        },
        String::from_utf8_lossy(&check.stdout).trim()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::AreaKind;

    #[test]
    fn only_learner_sections_may_change() {
        let running = Config::default();
        let mut new = running.clone();
        new.ppo.learning_rate = 1e-4;
        new.supervise.grace_ms = 1000;
        assert!(fixed_sections_differ(&running, &new).is_empty());
        *new.sim.envs.entry(AreaKind::Flat).or_default() += 1;
        new.run.seed += 1;
        assert_eq!(fixed_sections_differ(&running, &new), ["[run]", "[sim]"]);
    }
}
