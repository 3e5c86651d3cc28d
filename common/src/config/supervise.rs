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
    /// Restarts allowed within any `window-s` seconds; one more exit ends the run. 0 ..= 1000.
    pub max_restarts: u32,
    /// Wait before a restart, doubled for each restart within the window (capped at 30 s). 0 ..= 600000.
    pub backoff_ms: u64,
    /// The window `max-restarts` counts over, seconds; 0 counts over the whole run. 0 ..= 86400.
    #[serde(default = "default_window_s")]
    pub window_s: u64,
}

/// Restarts count over the last 10 minutes unless a config says otherwise: a week-long run
/// survives a fault a day, a crash loop still ends the run within minutes.
fn default_window_s() -> u64 {
    600
}

impl RestartPolicy {
    /// A process that is never started again.
    pub const NEVER: Self = Self {
        restart: Restart::Never,
        max_restarts: 0,
        backoff_ms: 0,
        window_s: 0,
    };

    /// The window restarts count over; `None` counts over the whole run.
    pub fn window(&self) -> Option<std::time::Duration> {
        (self.window_s > 0).then(|| std::time::Duration::from_secs(self.window_s))
    }

    /// The wait before a restart that follows `n` restarts within the window.
    pub fn backoff(&self, n: u32) -> std::time::Duration {
        let ms = self.backoff_ms.saturating_mul(1 << n.min(16)).min(30_000);
        std::time::Duration::from_millis(ms)
    }

    /// Whether a process that exited (`success`) after `restarts` restarts within the window
    /// comes back.
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
    /// Default: on-failure, 5 restarts in 10 minutes, 1 s backoff (it resumes from its newest checkpoint).
    pub learner: RestartPolicy,
    /// Default: on-failure, 5 restarts in 10 minutes, 1 s backoff (the sim keeps its last estimates meanwhile).
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
            window_s: default_window_s(),
        };
        Self {
            learner: on_failure,
            estimator: on_failure,
            sim: RestartPolicy {
                restart: Restart::Never,
                max_restarts: 0,
                backoff_ms: 0,
                window_s: 0,
            },
            grace_ms: 5000,
        }
    }
}

impl SuperviseConfig {
    /// The restart policies.
    pub(super) fn validate_restarts(&self) -> Result<(), ConfigError> {
        for (field, p) in [
            ("supervise.learner", &self.learner),
            ("supervise.estimator", &self.estimator),
            ("supervise.sim", &self.sim),
        ] {
            if p.backoff_ms > 600_000 || p.max_restarts > 1000 || p.window_s > 86_400 {
                return Err(invalid(
                    field,
                    (p.backoff_ms, p.max_restarts, p.window_s),
                    "needs backoff-ms <= 600000, max-restarts <= 1000 and window-s <= 86400",
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
        assert_eq!(
            l.window().map(|w| w.as_secs()),
            Some(600),
            "the default window"
        );
        let e = c.supervise.estimator;
        assert!(e.restarts_after(false, 0) && !e.restarts_after(true, 0));
        assert!(!c.supervise.sim.restarts_after(false, 0));
        let err = parse("[supervise]\ngrace-ms = 5\n").expect_err("too short");
        assert!(err.to_string().contains("supervise.grace-ms"), "{err}");
        let whole = parse(
            "[supervise]\nlearner = { restart = \"always\", max-restarts = 2, backoff-ms = 0, window-s = 0 }\n",
        )
        .expect("valid");
        assert_eq!(
            whole.supervise.learner.window(),
            None,
            "0 counts the whole run"
        );
        let err = parse(
            "[supervise]\nestimator = { restart = \"always\", max-restarts = 2, backoff-ms = 0, window-s = 90000 }\n",
        )
        .expect_err("a window over a day");
        assert!(err.to_string().contains("supervise.estimator"), "{err}");
    }
}
