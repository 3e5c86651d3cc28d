//! `[supervise]`: how the launcher restarts and stops its processes (DESIGN §4).

use super::ConfigError;
use super::range::{count_in, invalid};
use serde::{Deserialize, Serialize};

/// When the launcher restarts a process that exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// An exit ends the run (a failure fails it).
    Never,
    /// Restart after a non-zero exit or a signal; a clean exit is final.
    OnFailure,
    /// Restart after any exit while the run goes on.
    Always,
}

/// One process's restart policy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct RestartPolicy {
    pub restart: Restart,
    /// Restarts allowed over the run; one more exit ends it. 0 ..= 1000.
    pub max_restarts: u32,
    /// Wait before the first restart, doubled for each further one (capped at 30 s). 0 ..= 600000.
    pub backoff_ms: u64,
}

impl RestartPolicy {
    /// The wait before restart number `n` (0-based).
    pub fn backoff(&self, n: u32) -> std::time::Duration {
        let ms = self.backoff_ms.saturating_mul(1 << n.min(16)).min(30_000);
        std::time::Duration::from_millis(ms)
    }

    /// Whether a process that exited (`success`) after `restarts` restarts comes back.
    pub fn restarts_after(&self, success: bool, restarts: u32) -> bool {
        let wanted = match self.restart {
            Restart::Never => false,
            Restart::OnFailure => !success,
            Restart::Always => true,
        };
        wanted && restarts < self.max_restarts
    }
}

/// How `lavatube run` supervises its processes (DESIGN §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct SuperviseConfig {
    /// Default: on-failure, 5 restarts, 1 s backoff (it resumes from its newest checkpoint).
    pub learner: RestartPolicy,
    /// Default: on-failure, 5 restarts, 1 s backoff (the sim keeps its last estimates meanwhile).
    pub estimator: RestartPolicy,
    /// Default: never (the sim is the run; its failure ends it).
    pub sim: RestartPolicy,
    /// How long a process gets to stop on request before SIGTERM, and again before SIGKILL,
    /// milliseconds. 100 ..= 600000. Default 5000.
    pub grace_ms: u64,
}

impl Default for SuperviseConfig {
    fn default() -> Self {
        let on_failure = RestartPolicy {
            restart: Restart::OnFailure,
            max_restarts: 5,
            backoff_ms: 1000,
        };
        Self {
            learner: on_failure,
            estimator: on_failure,
            sim: RestartPolicy {
                restart: Restart::Never,
                max_restarts: 0,
                backoff_ms: 0,
            },
            grace_ms: 5000,
        }
    }
}

impl SuperviseConfig {
    /// The restart policies.
    pub(super) fn validate_restarts(&self) -> Result<(), ConfigError> {
        for (field, backoff, max) in [
            (
                "supervise.learner",
                self.learner.backoff_ms,
                self.learner.max_restarts,
            ),
            (
                "supervise.estimator",
                self.estimator.backoff_ms,
                self.estimator.max_restarts,
            ),
            ("supervise.sim", self.sim.backoff_ms, self.sim.max_restarts),
        ] {
            if backoff > 600_000 || max > 1000 {
                return Err(invalid(
                    field,
                    (backoff, max),
                    "needs backoff-ms <= 600000 and max-restarts <= 1000",
                ));
            }
        }
        Ok(())
    }

    /// `grace-ms`, checked apart from the restart policies: see [`Config::validate`](super::Config::validate).
    pub(super) fn validate_grace(&self) -> Result<(), ConfigError> {
        count_in("supervise.grace-ms", self.grace_ms, 100, 600_000)
    }
}

#[cfg(test)]
mod tests {
    use crate::config::tests::parse;

    #[test]
    fn restart_policies_decide_and_back_off() {
        let c = parse(
            "[supervise]\nlearner = { restart = \"always\", max-restarts = 2, backoff-ms = 500 }\n",
        )
        .expect("valid");
        let l = c.supervise.learner;
        assert!(l.restarts_after(true, 0) && l.restarts_after(false, 1));
        assert!(!l.restarts_after(false, 2), "the third exit is final");
        assert_eq!(
            [l.backoff(0), l.backoff(1), l.backoff(2), l.backoff(10)].map(|d| d.as_millis()),
            [500, 1000, 2000, 30_000]
        );
        let e = c.supervise.estimator;
        assert!(e.restarts_after(false, 0) && !e.restarts_after(true, 0));
        assert!(!c.supervise.sim.restarts_after(false, 0));
        let err = parse("[supervise]\ngrace-ms = 5\n").expect_err("too short");
        assert!(err.to_string().contains("supervise.grace-ms"), "{err}");
    }
}
