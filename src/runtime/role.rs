//! What each process of a run is for. The runtime matches on a [`Role`], never on a process
//! name, and derives from it the log file and the name shown to the user
//! ([`Binaries::of`](super::Binaries::of) gives its executable).

use common::config::PolicySlot;

/// One process of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Role {
    /// Trains (or, frozen, only serves) the policy of one slot (DESIGN §4, §5).
    Learner(PolicySlot),
    /// Classifies terrain online and publishes the estimates (SPEC S7).
    Estimator,
    /// Steps the envs and acts (SPEC S1–S5).
    Sim,
    /// Carries rollout chunks and policies between the hosts of a run (DESIGN §9).
    Bridge,
    /// Writes the run's telemetry and terrain estimates to a Rerun recording (`run.record`).
    Recorder,
    /// `lavatube bench`'s reading process: counts every telemetry tick and rollout chunk.
    Reader,
    /// `lavatube bench`'s receiving end of the transport comparison.
    Echo,
}

impl Role {
    /// The name in logs, summaries and the progress output; also the log file's stem.
    pub fn name(self) -> &'static str {
        match self {
            Self::Learner(slot) => slot.learner_name(),
            Self::Estimator => "estimator",
            Self::Sim => "sim",
            Self::Bridge => "bridge",
            Self::Recorder => "recorder",
            Self::Reader => "reader",
            Self::Echo => "echo",
        }
    }

    pub fn is_learner(self) -> bool {
        matches!(self, Self::Learner(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_distinct_and_learners_name_their_slot() {
        let all = [
            Role::Learner(PolicySlot::General),
            Role::Learner(PolicySlot::Flat),
            Role::Learner(PolicySlot::Rough),
            Role::Estimator,
            Role::Sim,
            Role::Bridge,
            Role::Recorder,
            Role::Reader,
            Role::Echo,
        ];
        let names: std::collections::BTreeSet<_> = all.iter().map(|r| r.name()).collect();
        assert_eq!(names.len(), all.len());
        assert_eq!(Role::Learner(PolicySlot::Flat).name(), "learner-flat");
        assert!(Role::Learner(PolicySlot::Rough).is_learner() && !Role::Sim.is_learner());
    }
}
