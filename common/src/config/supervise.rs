//! `[supervise]`: how the launcher restarts and stops its processes (DESIGN §4).

use super::setting::{Setting, choices, count, settings};
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

impl Setting for Restart {}

settings! {
    /// One process's restart policy.
    #[derive(Copy)]
    pub struct RestartPolicy, required {
        /// When the process comes back after it exits: `never`, `on-failure` or `always`.
        pub restart: Restart => choices::<Restart>(), "", Advanced;
        /// Restarts allowed within any `window-s` seconds; one more exit ends the run.
        pub max_restarts: u32 => count(0, 1000), "restarts", Advanced;
        /// Wait before a restart, doubled for each restart within the window (capped at 30 s).
        pub backoff_ms: u64 => count(0, 600_000), "ms", Advanced;
        /// The window `max-restarts` counts over; 0 counts over the whole run.
        #[serde(default = "default_window_s")]
        pub window_s: u64 = default_window_s() => count(0, 86_400), "s", Advanced;
    }
}

/// Restarts count over the last 10 minutes unless a config says otherwise: a week-long run
/// survives a fault a day, a crash loop still ends the run within minutes.
const fn default_window_s() -> u64 {
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

    /// Restarted after a failure, 5 times within the default window, after 1 s at first.
    const ON_FAILURE: Self = Self {
        restart: Restart::OnFailure,
        max_restarts: 5,
        backoff_ms: 1000,
        window_s: default_window_s(),
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

settings! {
    /// How `lavatube run` supervises its processes (DESIGN §4).
    pub struct SuperviseConfig {
        /// The learners' policy (by default on failure, 5 restarts in 10 minutes, 1 s
        /// backoff): a learner resumes from its newest checkpoint.
        pub learner: RestartPolicy = RestartPolicy::ON_FAILURE;
        /// estimator-proc's policy (by default as the learners'): the sim keeps its last
        /// estimates meanwhile.
        pub estimator: RestartPolicy = RestartPolicy::ON_FAILURE;
        /// The sim's policy (by default never: the sim is the run; its failure ends it).
        pub sim: RestartPolicy = RestartPolicy::NEVER;
        /// How long a process gets to stop on request before SIGTERM, and again before
        /// SIGKILL.
        pub grace_ms: u64 = 5000 => count(100, 600_000), "ms", Advanced;
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
