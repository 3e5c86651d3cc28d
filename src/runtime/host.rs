//! Which part of a run this host runs (DESIGN §9): all of it, or one side of a run across
//! hosts, whose sides meet through their bridges over Zenoh.

use super::Role;

/// This host's part of a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Host {
    /// Every process on this host, meeting in its shared memory (the default).
    Whole,
    /// The learner host: the learners and a bridge listening on `listen` for sim hosts.
    Learner { listen: String },
    /// A sim host: estimator, sim and a bridge connected to the learner host at `connect`;
    /// its chunks carry `source`.
    Sim { connect: String, source: u32 },
}

impl Host {
    /// Whether this host runs a process of `role`.
    pub fn starts(&self, role: Role) -> bool {
        match (self, role) {
            (_, Role::Reader | Role::Echo) => false,
            (Self::Whole, r) => r != Role::Bridge,
            (Self::Learner { .. }, r) => r.is_learner() || r == Role::Bridge,
            (Self::Sim { .. }, r) => !r.is_learner(),
        }
    }

    /// The bridge's arguments before the run's `--config` and `--run-id`; none on a whole host.
    pub fn bridge_args(&self) -> Option<Vec<String>> {
        match self {
            Self::Whole => None,
            Self::Learner { listen } => {
                Some(vec!["learner".into(), "--listen".into(), listen.clone()])
            }
            Self::Sim { connect, source } => Some(vec![
                "sim".into(),
                "--connect".into(),
                connect.clone(),
                "--source".into(),
                source.to_string(),
            ]),
        }
    }

    /// The sim's source id: 0 beside the learner.
    pub fn source(&self) -> u32 {
        match self {
            Self::Sim { source, .. } => *source,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::PolicySlot;

    #[test]
    fn each_host_starts_its_side_of_the_run() {
        let learner = Role::Learner(PolicySlot::General);
        let roles = [learner, Role::Estimator, Role::Sim, Role::Bridge];
        let started = |h: &Host| roles.map(|r| h.starts(r));
        assert_eq!(started(&Host::Whole), [true, true, true, false]);
        let l = Host::Learner {
            listen: "tcp/127.0.0.1:7447".into(),
        };
        assert_eq!(started(&l), [true, false, false, true]);
        let s = Host::Sim {
            connect: "tcp/127.0.0.1:7447".into(),
            source: 2,
        };
        assert_eq!(started(&s), [false, true, true, true]);
        assert_eq!((Host::Whole.source(), s.source()), (0, 2));
        assert_eq!(Host::Whole.bridge_args(), None);
        assert_eq!(
            s.bridge_args().expect("a sim host's bridge").join(" "),
            "sim --connect tcp/127.0.0.1:7447 --source 2"
        );
    }
}
