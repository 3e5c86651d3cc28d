//! Rollout transitions: what the sim records per env and decision step, and the learner
//! trains on. The same `repr(C)` record is the element of the `rollout` service's slice.

use crate::wire::RolloutHeader;
use crate::{ACT_DIM, OBS_DIM};
use iceoryx2::prelude::ZeroCopySend;

/// One env's decision step. `terminated` and `truncated` are separate (SPEC S3): on
/// truncation the learner bootstraps from `final_obs`, the observation of the state the
/// episode was cut in (before the next target was drawn); on termination it does not.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.Transition.v1")]
pub struct Transition {
    /// Observation the action was chosen from (raw, not normalised). `[obs]`
    pub obs: [f32; OBS_DIM],
    /// The sampled action before clipping (the log-prob refers to it). `[act]`
    pub action: [f32; ACT_DIM],
    /// Observation at truncation; meaningful only when `truncated != 0`. `[obs]`
    pub final_obs: [f32; OBS_DIM],
    /// Log-probability of `action` under the behaviour policy.
    pub logprob: f32,
    pub reward: f32,
    /// Policy version that chose the action.
    pub policy_version: u32,
    /// Env index.
    pub env: u32,
    /// 1 when the episode ended in a terminal state after this step.
    pub terminated: u8,
    /// 1 when the episode was cut (time limit, fault) after this step.
    pub truncated: u8,
    /// 1 when the episode ended by reaching its target after this step.
    pub success: u8,
    /// True terrain under the robot (0 flat, 1 rough; on the mixed course, the part it is on).
    pub area: u8,
    /// Terrain class the estimator assigned at this step (255: none yet).
    pub estimated_class: u8,
    /// Policy slot that acted (0 general, 1 flat, 2 rough).
    pub slot: u8,
    pub _reserved: [u8; 2],
}

impl Default for Transition {
    fn default() -> Self {
        Self {
            obs: [0.0; OBS_DIM],
            action: [0.0; ACT_DIM],
            final_obs: [0.0; OBS_DIM],
            logprob: 0.0,
            reward: 0.0,
            policy_version: 0,
            env: 0,
            terminated: 0,
            truncated: 0,
            success: 0,
            area: 0,
            estimated_class: u8::MAX,
            slot: 0,
            _reserved: [0; 2],
        }
    }
}

impl Transition {
    /// Every float (observations, action, log-prob, reward) is finite.
    pub fn is_finite(&self) -> bool {
        self.obs
            .iter()
            .chain(&self.action)
            .chain(&self.final_obs)
            .chain([&self.logprob, &self.reward])
            .all(|x| x.is_finite())
    }
}

/// Why a rollout chunk with header `h` and slice `data` must be refused, if it must: a
/// slice that is not `steps × envs` transitions plus `envs` bootstrap observations, an env
/// id outside the chunk's envs, a slot that is no policy slot, or a non-finite value. The
/// sim never sends such a chunk; a receiver drops one and goes on (DESIGN §2).
pub fn chunk_refusal(h: &RolloutHeader, data: &[Transition]) -> Option<&'static str> {
    let (t, n) = (h.steps as usize, h.envs as usize);
    if n == 0 || data.len() != t * n + n {
        return Some("wrong chunk size");
    }
    let (transitions, boot) = data.split_at(t * n);
    if transitions.iter().any(|x| x.env as usize >= n) {
        return Some("env id out of range");
    }
    if transitions
        .iter()
        .any(|x| usize::from(x.slot) >= crate::config::PolicySlot::ALL.len())
    {
        return Some("unknown policy slot");
    }
    if !transitions.iter().all(Transition::is_finite)
        || !boot.iter().all(|b| b.obs.iter().all(|x| x.is_finite()))
    {
        return Some("non-finite value");
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn hostile_chunks_are_refused_by_kind() {
        // 2 steps × 2 envs, then 2 bootstrap entries.
        let h = RolloutHeader {
            steps: 2,
            envs: 2,
            ..RolloutHeader::default()
        };
        let good: Vec<Transition> = (0..6)
            .map(|i| Transition {
                env: i % 2,
                ..Transition::default()
            })
            .collect();
        assert_eq!(chunk_refusal(&h, &good), None);
        assert_eq!(chunk_refusal(&h, &good[..5]), Some("wrong chunk size"));
        let no_envs = RolloutHeader { envs: 0, ..h };
        assert_eq!(chunk_refusal(&no_envs, &[]), Some("wrong chunk size"));
        let mut bad = good.clone();
        bad[3].env = 2;
        assert_eq!(chunk_refusal(&h, &bad), Some("env id out of range"));
        let mut bad = good.clone();
        bad[0].slot = 6;
        assert_eq!(chunk_refusal(&h, &bad), Some("unknown policy slot"));
        bad[0].slot = 5;
        assert_eq!(chunk_refusal(&h, &bad), None, "the sand slot");
        for poison in [f32::NAN, f32::INFINITY] {
            let mut bad = good.clone();
            bad[1].reward = poison;
            assert_eq!(chunk_refusal(&h, &bad), Some("non-finite value"));
            let mut bad = good.clone();
            bad[5].obs[3] = poison;
            assert_eq!(
                chunk_refusal(&h, &bad),
                Some("non-finite value"),
                "bootstrap"
            );
        }
        // A bootstrap entry carries only its observation: its other fields are not read.
        let mut boot_env = good.clone();
        boot_env[4].env = 99;
        assert_eq!(chunk_refusal(&h, &boot_env), None);
    }

    #[test]
    fn transition_layout_is_pinned() {
        let msg = "layout changed: bump the version in the type name";
        assert_eq!(size_of::<Transition>(), 112, "{msg}");
        assert_eq!(align_of::<Transition>(), 4, "{msg}");
        assert_eq!(offset_of!(Transition, action), 40, "{msg}");
        assert_eq!(offset_of!(Transition, final_obs), 48, "{msg}");
        assert_eq!(offset_of!(Transition, logprob), 88, "{msg}");
        assert_eq!(offset_of!(Transition, policy_version), 96, "{msg}");
        assert_eq!(offset_of!(Transition, terminated), 104, "{msg}");
        assert_eq!(offset_of!(Transition, area), 107, "{msg}");
        assert_eq!(offset_of!(Transition, estimated_class), 108, "{msg}");
        assert_eq!(offset_of!(Transition, slot), 109, "{msg}");
    }
}
