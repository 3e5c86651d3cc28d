//! Rollout transitions: what the sim records per env and decision step, and the learner
//! trains on. The same `repr(C)` record is the element of the `rollout` service's slice.

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

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

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
