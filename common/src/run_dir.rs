//! What a run directory holds, by name: every process and command that writes or reads a
//! run's files takes the names from here, so they cannot drift apart.
//!
//! ```text
//! <run-dir>/
//!   config.toml           the resolved config the run started with
//!   summary.json          how the run ended, written last
//!   telemetry.csv         the sim's ticks, with run.telemetry-csv
//!   track.csv             every robot's thinned path, targets and endings
//!   map.png               the world with those paths, drawn when the run ends
//!   launcher/             the launcher's TensorBoard events (steps/s, lag, terrain accuracy)
//!   learner-config-N.toml the config of the N-th swapped-in learner
//!   logs/<process>.log    each process's output
//!   metrics.csv           one row per update of the general model's learner
//!   events.out.tfevents.* the same rows as TensorBoard scalars
//!   curves.png            those rows drawn
//!   checkpoints/checkpoint-<update, 10 digits>.ckpt
//!   learner-flat/, learner-rough/   the same three for each specialist's learner
//! ```

use std::path::{Path, PathBuf};

use crate::config::PolicySlot;

/// The resolved config a run started with.
pub const CONFIG_TOML: &str = "config.toml";
/// How the run ended, written when it finishes.
pub const SUMMARY_JSON: &str = "summary.json";
/// The sim's telemetry, one row per tick, when `run.telemetry-csv` is on.
pub const TELEMETRY_CSV: &str = "telemetry.csv";
/// Every robot's thinned path, targets and endings (`common::track`), written by the sim.
pub const TRACK_CSV: &str = "track.csv";
/// The world every episode drew, when `sim.randomize` draws any (written by the sim).
pub const WORLDS_CSV: &str = "worlds.csv";
/// The map of the world with the robots' paths, drawn from [`TRACK_CSV`].
pub const MAP_PNG: &str = "map.png";
/// The directory of the processes' log files (see [`log_file`]).
pub const LOGS: &str = "logs";
/// A learner's per-update metrics, in its [`learner_dir`].
pub const METRICS_CSV: &str = "metrics.csv";
/// A learner's learning curves, drawn from [`METRICS_CSV`] beside it.
pub const CURVES_PNG: &str = "curves.png";
/// A learner's checkpoint directory, in its [`learner_dir`] (see [`checkpoint_file`]).
pub const CHECKPOINTS: &str = "checkpoints";

const CHECKPOINT_PREFIX: &str = "checkpoint-";
const CHECKPOINT_SUFFIX: &str = ".ckpt";

/// Where a slot's learner writes metrics, curves and checkpoints: the run directory for
/// `general`, a subdirectory named after the learner process for each specialist.
pub fn learner_dir(run_dir: &Path, slot: PolicySlot) -> PathBuf {
    match slot {
        PolicySlot::General => run_dir.to_path_buf(),
        s => run_dir.join(s.learner_name()),
    }
}

/// The file name of the checkpoint taken after `update` updates; zero-padded so that names
/// sort as updates do.
pub fn checkpoint_file(update: u64) -> String {
    format!("{CHECKPOINT_PREFIX}{update:010}{CHECKPOINT_SUFFIX}")
}

/// The update of a [`checkpoint_file`] name; `None` for any other file.
pub fn parse_checkpoint_file(name: &str) -> Option<u64> {
    name.strip_prefix(CHECKPOINT_PREFIX)?
        .strip_suffix(CHECKPOINT_SUFFIX)?
        .parse()
        .ok()
}

/// The log file of process `name`, in the run directory's [`LOGS`].
pub fn log_file(run_dir: &Path, name: &str) -> PathBuf {
    run_dir.join(LOGS).join(format!("{name}.log"))
}

/// The file name of the resolved config of the `n`-th learner swapped into a run.
pub fn swapped_learner_config(n: u32) -> String {
    format!("learner-config-{n}.toml")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learner_dirs_general_in_place_specialists_below() {
        let run = Path::new("runs/r1");
        assert_eq!(learner_dir(run, PolicySlot::General), run);
        assert_eq!(
            learner_dir(run, PolicySlot::Flat),
            Path::new("runs/r1/learner-flat")
        );
        assert_eq!(
            learner_dir(run, PolicySlot::Rough),
            Path::new("runs/r1/learner-rough")
        );
    }

    #[test]
    fn checkpoint_names_pad_to_ten_digits_and_parse_back() {
        assert_eq!(checkpoint_file(1), "checkpoint-0000000001.ckpt");
        assert_eq!(checkpoint_file(12_345), "checkpoint-0000012345.ckpt");
        for update in [0, 7, 9_999_999_999, 10_000_000_000] {
            assert_eq!(
                parse_checkpoint_file(&checkpoint_file(update)),
                Some(update)
            );
        }
        for other in [
            "checkpoint-1.ckpt.tmp",
            ".checkpoint-0000000001.ckpt.tmp-1",
            "checkpoint-.ckpt",
            "checkpoint-00x1.ckpt",
            "metrics.csv",
        ] {
            assert_eq!(parse_checkpoint_file(other), None, "{other}");
        }
    }

    #[test]
    fn logs_and_swapped_configs() {
        assert_eq!(
            log_file(Path::new("r"), "learner-flat"),
            Path::new("r/logs/learner-flat.log")
        );
        assert_eq!(swapped_learner_config(2), "learner-config-2.toml");
    }
}
