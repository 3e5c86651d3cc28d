//! The policy set and switching (DESIGN §5, SPEC S8): the sim holds one policy per slot
//! (general, flat, rough), filled as learners publish; each env acts with the slot the config
//! names or, when switching, with the specialist for the estimator's current class — changed
//! only after the new estimate has held for a dwell time, so one noisy window does not flip it.

use crate::controllers::{Actor, PolicyController};
use common::config::{Acting, PolicySlot};

/// The sim's policies, one per slot, with the version each acts at.
pub struct PolicySet {
    slots: [Option<PolicyController>; PolicySlot::ALL.len()],
    versions: [u32; PolicySlot::ALL.len()],
}

impl PolicySet {
    /// A set with one policy; more slots fill as their learners publish.
    pub fn new(slot: PolicySlot, ctrl: PolicyController, version: u32) -> Self {
        let mut set = Self {
            slots: std::array::from_fn(|_| None),
            versions: [0; PolicySlot::ALL.len()],
        };
        set.insert(slot, ctrl, version);
        set
    }

    pub fn insert(&mut self, slot: PolicySlot, ctrl: PolicyController, version: u32) {
        self.slots[slot.index()] = Some(ctrl);
        self.versions[slot.index()] = version;
    }

    pub fn get_mut(&mut self, slot: PolicySlot) -> Option<&mut PolicyController> {
        self.slots[slot.index()].as_mut()
    }

    pub fn set_version(&mut self, slot: PolicySlot, version: u32) {
        self.versions[slot.index()] = version;
    }

    pub fn version(&self, slot: PolicySlot) -> u32 {
        self.versions[slot.index()]
    }

    /// The slot that acts when `wanted` is asked for: `wanted` if it has a policy, else
    /// `general`, else the first slot that has one (a set is never empty).
    pub fn resolve(&self, wanted: PolicySlot) -> PolicySlot {
        [wanted, PolicySlot::General]
            .into_iter()
            .chain(PolicySlot::ALL)
            .find(|s| self.slots[s.index()].is_some())
            .unwrap_or(wanted)
    }

    /// Samples an action for `obs` with the slot that acts for `wanted`, drawing from
    /// `actor`'s stream; returns that slot, its version, the unclipped action and its
    /// log-probability.
    pub fn sample(
        &self,
        wanted: PolicySlot,
        obs: &[f32; common::OBS_DIM],
        actor: &mut Actor,
    ) -> (PolicySlot, u32, [f32; common::ACT_DIM], f32) {
        let slot = self.resolve(wanted);
        let version = self.version(slot);
        match self.slots[slot.index()].as_ref() {
            Some(c) => {
                let (a, lp) = c.sample(obs, actor);
                (slot, version, a, lp)
            }
            None => unreachable!("PolicySet::new fills a slot and none is ever emptied"),
        }
    }
}

/// Each env's wanted slot under the configured [`Acting`] rule.
pub struct Switcher {
    fixed: Option<PolicySlot>,
    /// Ticks a new estimate must hold before an env leaves each slot (by index).
    dwell: [u32; PolicySlot::ALL.len()],
    current: Vec<PolicySlot>,
    candidate: Vec<Option<PolicySlot>>,
    held: Vec<u32>,
}

impl Switcher {
    /// Each of `envs` envs acting under `acting`; leaving a slot takes `dwell(slot)` ticks of
    /// a new estimate ([`common::config::SimConfig::dwell_leaving`]).
    pub fn new(acting: Acting, dwell: impl Fn(PolicySlot) -> u32, envs: usize) -> Self {
        let start = acting.fixed().unwrap_or(PolicySlot::General);
        Self {
            fixed: acting.fixed(),
            dwell: PolicySlot::ALL.map(dwell),
            current: vec![start; envs],
            candidate: vec![None; envs],
            held: vec![0; envs],
        }
    }

    /// Takes one tick of estimator classes (one per env; unknown classes change nothing) and
    /// returns each env's wanted slot. SPEC S8: the specialist for the estimated terrain,
    /// after the estimate has held for `dwell` consecutive ticks (the slot's leave dwell,
    /// where it has one).
    pub fn update(&mut self, classes: &[u8]) -> &[PolicySlot] {
        if self.fixed.is_some() {
            return &self.current;
        }
        for (i, &class) in classes.iter().enumerate().take(self.current.len()) {
            let Some(target) = PolicySlot::for_class(class) else {
                continue;
            };
            if target == self.current[i] {
                (self.candidate[i], self.held[i]) = (None, 0);
                continue;
            }
            if self.candidate[i] == Some(target) {
                self.held[i] += 1;
            } else {
                (self.candidate[i], self.held[i]) = (Some(target), 1);
            }
            if self.held[i] >= self.dwell[self.current[i].index()] {
                self.current[i] = target;
                (self.candidate[i], self.held[i]) = (None, 0);
            }
        }
        &self.current
    }

    pub fn wanted(&self) -> &[PolicySlot] {
        &self.current
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::AreaKind;
    use common::wire::CLASS_UNKNOWN;
    use common::{ACT_DIM, OBS_DIM, Policy, PolicyLayout};
    use std::collections::BTreeMap;

    /// SPEC S8: a new estimate must hold `dwell` ticks; a flicker restarts the count; unknown
    /// classes neither switch nor reset.
    #[test]
    fn switching_waits_for_the_dwell_time() {
        use PolicySlot::{Flat, General, Rough};
        let mut s = Switcher::new(Acting::Switch, |_| 3, 1);
        let mut seen = Vec::new();
        for class in [CLASS_UNKNOWN, 0, 0, 0, 1, 1, 0, 1, 1, CLASS_UNKNOWN, 1] {
            seen.push(s.update(&[class])[0]);
        }
        assert_eq!(
            seen,
            [
                General, General, General, Flat, Flat, Flat, Flat, Flat, Flat, Flat, Rough
            ]
        );
        let mut fixed = Switcher::new(Acting::Rough, |_| 1, 2);
        assert_eq!(fixed.update(&[0, 0]), [Rough, Rough]);
    }

    /// Beyond SPEC S8's two classes: a K-kind estimate is a kind's code, and each code
    /// switches to that kind's specialist.
    #[test]
    fn kind_codes_switch_to_their_specialists() {
        use PolicySlot::{Flat, Gravel, Rough, Slope};
        let mut s = Switcher::new(Acting::Switch, |_| 1, 4);
        assert_eq!(s.update(&[0, 1, 3, 4]), [Flat, Rough, Slope, Gravel]);
        // Code 2 (the mixed course) names no terrain: nothing changes.
        assert_eq!(s.update(&[2, 2, 2, 2]), [Flat, Rough, Slope, Gravel]);
    }

    /// A slot with a leave dwell is entered after the dwell and left only after its own.
    #[test]
    fn a_leave_dwell_holds_its_slot_longer() {
        use PolicySlot::{Flat, General, Sand};
        let cfg = common::config::SimConfig {
            switch_dwell: 2,
            leave_dwell: BTreeMap::from([(Sand, 4)]),
            ..Default::default()
        };
        let mut s = Switcher::new(Acting::Switch, |s| cfg.dwell_leaving(s), 1);
        let (flat, sand) = (AreaKind::Flat.code(), AreaKind::Sand.code());
        let mut seen = Vec::new();
        for class in [
            flat, flat, sand, sand, flat, flat, flat, sand, flat, flat, flat, flat,
        ] {
            seen.push(s.update(&[class])[0]);
        }
        assert_eq!(
            seen,
            [
                General, Flat, Flat, Sand, Sand, Sand, Sand, Sand, Sand, Sand, Sand, Flat
            ]
        );
    }

    #[test]
    fn the_set_falls_back_to_general_then_to_any_policy() {
        let policy = |bias: f32| {
            let layout = PolicyLayout::new(OBS_DIM, &[4], ACT_DIM);
            let w = vec![bias; layout.len()];
            PolicyController::new(Policy::new(layout, w, 10.0).expect("policy"), false, 1)
        };
        let mut policies = PolicySet::new(PolicySlot::Rough, policy(0.1), 7);
        assert_eq!(policies.resolve(PolicySlot::Flat), PolicySlot::Rough);
        policies.insert(PolicySlot::General, policy(0.2), 3);
        assert_eq!(policies.resolve(PolicySlot::Flat), PolicySlot::General);
        assert_eq!(policies.resolve(PolicySlot::Rough), PolicySlot::Rough);
        let mut actor = Actor::for_env(1, 0);
        let (slot, version, _, _) = policies.sample(PolicySlot::Rough, &[0.0; OBS_DIM], &mut actor);
        assert_eq!((slot, version), (PolicySlot::Rough, 7));
    }
}
