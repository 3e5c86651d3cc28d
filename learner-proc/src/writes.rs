//! Writes a learner can live without for a while: checkpoints and metrics rows. When one fails
//! (a full disk, a lost mount) training goes on; the previous checkpoint stays whole (they are
//! written atomically), the next one is tried at its time, and the failures are counted for
//! the launcher's summary. The log gets one error when writes of a kind start failing and one
//! line when they work again, not one per update: a small metrics row that still fits does not
//! end the spell of a checkpoint that does not.

use crate::LearnerError;
use std::collections::BTreeSet;

#[derive(Debug, Default)]
pub struct Writes {
    failures: u32,
    /// The kinds of write whose last attempt failed.
    failing: BTreeSet<&'static str>,
}

impl Writes {
    /// `result` of writing `what`: the value, or `None` after counting (and, for the first
    /// of a run of failures, logging) the failure.
    pub fn attempt<T>(&mut self, what: &'static str, result: Result<T, LearnerError>) -> Option<T> {
        match result {
            Ok(v) => {
                if self.failing.remove(what) {
                    tracing::info!(what, failures = self.failures, "writes work again");
                }
                Some(v)
            }
            Err(e) => {
                self.failures = self.failures.saturating_add(1);
                if self.failing.insert(what) {
                    tracing::error!(
                        what,
                        error = %e,
                        "write failed; training goes on, the previous checkpoint stays, and the write is tried again next time"
                    );
                }
                None
            }
        }
    }

    /// Failed writes so far.
    pub fn failures(&self) -> u32 {
        self.failures
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// What a full disk answers: ENOSPC (28 on Linux).
    fn full() -> Result<(), LearnerError> {
        Err(LearnerError::io("writing", Path::new("c.ckpt"))(
            std::io::Error::from_raw_os_error(28),
        ))
    }

    #[test]
    fn failures_are_counted_and_training_goes_on() {
        let mut w = Writes::default();
        assert_eq!(w.attempt("checkpoint", Ok(5)), Some(5));
        assert_eq!(w.attempt("checkpoint", full()), None);
        assert_eq!(w.attempt("metrics", full()), None);
        assert_eq!(w.failures(), 2);
        assert_eq!(w.failing.len(), 2);
        assert_eq!(w.attempt("metrics", Ok(())), Some(()));
        assert!(
            w.failing.contains("checkpoint"),
            "a metrics row that fits does not end the checkpoints' failing spell"
        );
        assert_eq!(w.attempt("checkpoint", Ok(())), Some(()));
        assert!(w.failing.is_empty(), "a write that works ends its spell");
        assert_eq!(w.failures(), 2, "the count is of failures, not spells");
    }
}
