//! `[run]`: how runs are named, seeded and paced, and the policy slots their learners fill.

use super::range::invalid;
use super::setting::{Setting, choices, count, flag, form, real, settings};
use super::{Acting, ConfigError, PolicySlot};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

settings! {
    /// How runs are named, seeded and paced.
    pub struct RunConfig {
        /// Master seed; every process derives its streams from it.
        pub seed: u64 = 1 => count(0, u64::MAX), "", Essential;
        /// `sync`: the sim waits for the policy learned from each rollout (on-policy PPO);
        /// `async`: the sim never waits.
        pub mode: LearnMode = LearnMode::Sync => choices::<LearnMode>(), "", Essential;
        /// Total environment steps (decision steps summed over envs) to train for (SPEC S6);
        /// with `sim.acting = "external"` the gym client decides instead.
        pub total_steps: u64 = 2_500_000 => count(1, 10_000_000_000), "steps", Essential;
        /// Directory under which each run gets `<out-dir>/<run-id>/`.
        pub out_dir: PathBuf = PathBuf::from("runs") => form("a directory"), "", Essential;
        /// The learners of the run, one per policy slot (DESIGN §5). A `general` learner
        /// trains on every transition; a `flat` or `rough` one only on those the estimator
        /// assigned to its terrain (SPEC S8). Each slot at most once.
        pub learners: Vec<PolicySlot> = vec![PolicySlot::General] => choices::<PolicySlot>(), "", Essential;
        /// Start every learner from this learner checkpoint's weights and observation
        /// statistics with fresh counters and optimizer (a warm start, e.g. the general model
        /// from the flat one). Relative paths are relative to the config file; unset: none.
        pub init_from: Option<PathBuf> = None => form("a learner checkpoint file"), "", Essential;
        /// `ppo.learning-rate` of the learners started from `run.init-from` (it decays from
        /// there like every run's); unset: the `[ppo]` one.
        pub init_learning_rate: Option<f64> = None => real(1e-12, 1.0), "", Advanced;
        /// Learners that start from new weights at `ppo.learning-rate` although
        /// `run.init-from` is set: slots whose driving the warm start's policy would only
        /// unlearn slowly. Each in `run.learners`.
        pub fresh: Vec<PolicySlot> = Vec::new() => choices::<PolicySlot>(), "", Research;
        /// Policy slots served frozen from a learner checkpoint, never trained (evaluation,
        /// e.g. switching between fixed FTM and RTM): `{ flat = "ftm.ckpt", rough = "rtm.ckpt" }`.
        /// Relative paths are relative to the config file. No slot may also be in `learners`.
        pub frozen: BTreeMap<PolicySlot, PathBuf> = BTreeMap::new()
            => form("a table of policy slot -> learner checkpoint file"), "", Essential;
        /// The sim also writes every env's per-tick telemetry to `<run dir>/telemetry.csv`, as
        /// `sim-proc --telemetry` does (one row per env and tick; large).
        pub telemetry_csv: bool = false => flag(), "", Advanced;
        /// The launcher prints a summary line (step, elapsed, mean return, success, entropy,
        /// KL) each time a learner passes another multiple of this many env steps (ML-Agents'
        /// `summary_freq`); 0 prints none.
        pub summary_every: u64 = 50_000 => count(0, 10_000_000_000), "steps", Advanced;
        /// Record the run for the Rerun viewer: the file (`.rrd`, relative to the run
        /// directory) that recorder-proc writes the terrain, every robot's pose and trail and
        /// the estimator's signals to. Its death never stops the run. Unset: no recording.
        pub record: Option<PathBuf> = None => form("an .rrd file"), "", Advanced;
        /// Start estimator-proc, which classifies the terrain online (SPEC S8); false gives
        /// its CPU to the sim where no env switches and every learner is `general`.
        pub estimator: bool = true => flag(), "", Advanced;
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LearnMode {
    Sync,
    Async,
}

impl Setting for LearnMode {}

impl RunConfig {
    /// The checkpoint the learner of `slot` starts from: `run.init-from`, unless the slot is
    /// one of `run.fresh`.
    pub fn warm_start(&self, slot: PolicySlot) -> Option<&std::path::Path> {
        self.init_from
            .as_deref()
            .filter(|_| !self.fresh.contains(&slot))
    }

    /// The rules between fields (each field's own range is [`Setting::check`]'s); `acting`
    /// decides whether the run needs a policy slot.
    pub(super) fn validate(&self, acting: Acting) -> Result<(), ConfigError> {
        if acting == Acting::External {
            if !self.learners.is_empty() || !self.frozen.is_empty() {
                return Err(invalid(
                    "run.learners",
                    &self.learners,
                    "must be [] and run.frozen empty with sim.acting = \"external\": the gym client acts",
                ));
            }
        } else if (self.learners.is_empty() && self.frozen.is_empty())
            || (1..self.learners.len()).any(|i| self.learners[..i].contains(&self.learners[i]))
            || self.learners.iter().any(|s| self.frozen.contains_key(s))
        {
            return Err(invalid(
                "run.learners",
                &self.learners,
                "needs at least one slot (or a frozen one), each at most once and not also in run.frozen",
            ));
        }
        if let Some(p) = self.frozen.values().find(|p| !p.is_file()) {
            return Err(invalid("run.frozen", p, "file not found"));
        }
        if let Some(p) = &self.init_from
            && !p.is_file()
        {
            return Err(invalid("run.init-from", p, "file not found"));
        }
        if !self.fresh.is_empty()
            && (self.init_from.is_none() || self.fresh.iter().any(|s| !self.learners.contains(s)))
        {
            return Err(invalid(
                "run.fresh",
                &self.fresh,
                "names learners (slots in run.learners) that would otherwise start from run.init-from",
            ));
        }
        let specialists = self.learners.iter().any(|s| s.kind().is_some());
        if !self.estimator && (acting == Acting::Switch || specialists) {
            return Err(invalid(
                "run.estimator",
                false,
                "must be true: switching and specialist learners need the terrain estimate",
            ));
        }
        if let Some(r) = &self.record
            && r.extension().is_none_or(|e| e != "rrd")
        {
            return Err(invalid("run.record", r, "must name an .rrd file"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::parse;

    #[test]
    fn wire_indices_name_slots_and_nothing_past_them() {
        for slot in PolicySlot::ALL {
            let index = u32::try_from(slot.index()).expect("small");
            assert_eq!(PolicySlot::from_index(index), Some(slot));
        }
        assert_eq!(PolicySlot::from_index(1), Some(PolicySlot::Flat));
        assert_eq!(PolicySlot::from_index(6), None);
        assert_eq!(PolicySlot::from_index(u32::MAX), None);
    }

    #[test]
    fn learner_slots_are_checked() {
        let c = parse("[run]\nlearners = [\"flat\", \"rough\"]\n[sim]\nacting = \"switch\"\n")
            .expect("valid");
        assert_eq!(c.run.learners, [PolicySlot::Flat, PolicySlot::Rough]);
        assert_eq!(c.sim.acting.fixed(), None);
        assert_eq!(PolicySlot::for_class(1), Some(PolicySlot::Rough));
        assert_eq!(PolicySlot::Flat.class(), Some(0));
        // Beyond the paper: a specialist per terrain kind, its class the kind's code.
        assert_eq!(PolicySlot::for_class(3), Some(PolicySlot::Slope));
        assert_eq!(PolicySlot::Gravel.class(), Some(4));
        assert_eq!(
            PolicySlot::for_class(2),
            None,
            "the mixed course is no terrain"
        );
        assert_eq!(PolicySlot::parse("gravel"), Ok(PolicySlot::Gravel));
        assert_eq!(Acting::Slope.fixed(), Some(PolicySlot::Slope));
        let err = parse("[run]\nlearners = [\"flat\", \"flat\"]\n").expect_err("twice");
        assert!(err.to_string().contains("run.learners"), "{err}");
        let err = parse("[run]\ninit-from = \"/nonexistent.ckpt\"\n").expect_err("missing");
        assert!(err.to_string().contains("run.init-from"), "{err}");
        let err = parse("[run]\nfresh = [\"general\"]\n").expect_err("nothing to start from");
        assert!(err.to_string().contains("run.fresh"), "{err}");
        let err = parse("[run]\ninit-learning-rate = 2.0\n").expect_err("too fast");
        assert!(err.to_string().contains("run.init-learning-rate"), "{err}");
        let err = parse("[run]\nrecord = \"run.csv\"\n").expect_err("not .rrd");
        assert!(err.to_string().contains("run.record"), "{err}");
        assert!(parse("[run]\nrecord = \"run.rrd\"\n").is_ok());
        let err = parse("[run]\nestimator = false\n[sim]\nacting = \"switch\"\n")
            .expect_err("switching reads the estimate");
        assert!(err.to_string().contains("run.estimator"), "{err}");
        let err =
            parse("[run]\nestimator = false\nlearners = [\"rough\"]\n[sim]\nacting = \"rough\"\n")
                .expect_err("a specialist learns from the estimate's class");
        assert!(err.to_string().contains("run.estimator"), "{err}");
        assert!(parse("[run]\nestimator = false\n").is_ok());
    }

    #[test]
    fn fresh_learners_ignore_the_warm_start() {
        let dir = tempfile::tempdir().expect("tempdir");
        let ckpt = dir.path().join("general.ckpt");
        std::fs::write(&ckpt, b"weights").expect("write");
        let c = parse(&format!(
            "[run]\nlearners = [\"flat\", \"sand\"]\ninit-from = {:?}\nfresh = [\"sand\"]\n\
             [sim]\nacting = \"switch\"\n",
            ckpt.display().to_string()
        ))
        .expect("valid");
        assert_eq!(c.run.warm_start(PolicySlot::Flat), Some(ckpt.as_path()));
        assert_eq!(c.run.warm_start(PolicySlot::Sand), None);
        let mut stray = c.run.clone();
        stray.fresh = vec![PolicySlot::Rough];
        let err = stray.validate(Acting::Switch).expect_err("not a learner");
        assert!(err.to_string().contains("run.fresh"), "{err}");
    }

    #[test]
    fn an_external_client_acts_in_a_run_without_learners() {
        let gym = "[sim]\nacting = \"external\"\n";
        let err = parse(gym).expect_err("the default general learner");
        assert!(err.to_string().contains("gym client"), "{err}");
        let c = parse(&format!("[run]\nlearners = []\n{gym}")).expect("valid");
        assert_eq!(
            (c.sim.acting.fixed(), c.sim.external.timeout_s),
            (None, 30.0)
        );
        let err = parse("[run]\nlearners = []\n").expect_err("nobody acts");
        assert!(err.to_string().contains("at least one slot"), "{err}");
        let err = parse(&format!(
            "[run]\nlearners = []\n{gym}[sim.external]\ntimeout-s = 0.0\n"
        ))
        .expect_err("no time to answer");
        assert!(err.to_string().contains("sim.external.timeout-s"), "{err}");
    }
}
