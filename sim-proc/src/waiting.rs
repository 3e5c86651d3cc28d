//! How the sim in a run waits, for a policy or for a gym client: how long it sleeps between
//! checks, and how often it warns that it is still waiting.

use std::time::{Duration, Instant};

/// How long to sleep between checks while waiting for a policy (or a gym client).
pub(crate) const POLL: Duration = Duration::from_millis(100);

/// Paces "still waiting" warnings: due once per `every` of waiting.
pub(crate) struct Nag {
    since: Instant,
    next: Duration,
    every: Duration,
}

impl Nag {
    pub(crate) fn new(every: Duration) -> Self {
        Self {
            since: Instant::now(),
            next: every,
            every,
        }
    }

    /// Seconds waited so far, when a warning is due.
    pub(crate) fn due(&mut self) -> Option<u64> {
        let waited = self.since.elapsed();
        (waited >= self.next).then(|| {
            self.next += self.every;
            waited.as_secs()
        })
    }
}
