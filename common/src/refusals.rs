//! Messages a process refuses: each is counted by its kind, and the first of each kind is
//! logged, so a stream of bad messages from a broken or hostile peer cannot flood the log or
//! stop the process (DESIGN §2).

use std::collections::BTreeMap;

/// Refused messages so far, by kind (`"non-finite value"`, `"wrong chunk size"`, …).
#[derive(Debug, Default)]
pub struct Refusals {
    what: &'static str,
    counts: BTreeMap<&'static str, u64>,
}

impl Refusals {
    /// Refusals of `what` (e.g. "rollout chunk", "policy").
    pub fn new(what: &'static str) -> Self {
        Self {
            what,
            counts: BTreeMap::new(),
        }
    }

    /// Counts one refused message of `kind`; logs a warning the first time of each kind.
    pub fn refuse(&mut self, kind: &'static str, detail: &str) {
        self.refuse_many(kind, 1, detail);
    }

    /// Counts `count` refused messages of `kind`; logs a warning the first time of each kind.
    pub fn refuse_many(&mut self, kind: &'static str, count: u64, detail: &str) {
        if count == 0 {
            return;
        }
        let n = self.counts.entry(kind).or_default();
        let first = *n == 0;
        *n += count;
        if first {
            tracing::warn!(
                what = self.what,
                kind,
                detail,
                "refused (further ones of this kind are only counted)"
            );
        }
    }

    /// Refusals of `kind` so far.
    pub fn count(&self, kind: &str) -> u64 {
        self.counts.get(kind).copied().unwrap_or(0)
    }

    /// Every kind with its count, for the process's closing log line.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .counts
            .iter()
            .map(|(k, n)| format!("{k}: {n}"))
            .collect();
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(", ")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_is_counted() {
        let mut r = Refusals::new("policy");
        assert_eq!(r.summary(), "none");
        r.refuse("non-finite value", "weight 3");
        r.refuse("non-finite value", "weight 4");
        r.refuse("wrong length", "17 of 20");
        assert_eq!(r.count("non-finite value"), 2);
        assert_eq!(r.count("wrong length"), 1);
        assert_eq!(r.count("other"), 0);
        assert_eq!(r.summary(), "non-finite value: 2, wrong length: 1");
        r.refuse_many("wrong length", 5, "a batch");
        r.refuse_many("other", 0, "nothing");
        assert_eq!(r.summary(), "non-finite value: 2, wrong length: 6");
    }
}
