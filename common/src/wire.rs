//! Shared-memory message types (DESIGN §2), one section per direction. Every payload is
//! `repr(C)` with fixed-width fields and a versioned type name; slices carry the bulk data
//! and a user header carries the counters. Layout tests pin sizes and offsets.

use crate::policy::{MAX_HIDDEN, PolicyLayout};
use iceoryx2::prelude::ZeroCopySend;

// ---- sim → learner: `rollout` ---------------------------------------------------------------

/// Header of a rollout chunk. The slice holds `steps × envs` [`crate::Transition`]s in
/// `[step][env]` order, then `envs` more whose `obs` is each env's bootstrap observation.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.RolloutHeader.v1")]
pub struct RolloutHeader {
    /// Chunk sequence number from 0; a gap means the learner missed chunks.
    pub chunk: u64,
    /// Environment steps the sim has taken in total, including this chunk.
    pub env_steps: u64,
    /// Policy version that was acting when the chunk started.
    pub policy_version: u32,
    pub steps: u32,
    pub envs: u32,
    /// Policy slot this chunk is meant for (a learner trains one slot).
    pub slot: u32,
}

// ---- learner → sim: `policy` ----------------------------------------------------------------

/// Header of a policy message; the slice is the flat actor in `crate::policy`'s layout.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.PolicyHeader.v1")]
pub struct PolicyHeader {
    /// Monotonic per slot, continued across learner restarts.
    pub version: u32,
    pub slot: u32,
    pub obs_dim: u32,
    pub act_dim: u32,
    pub n_hidden: u32,
    pub hidden: [u32; MAX_HIDDEN],
    pub obs_clip: f32,
    /// PPO updates the learner has done.
    pub updates: u64,
    /// Environment steps the policy has learned from.
    pub env_steps: u64,
}

impl PolicyHeader {
    pub fn new(layout: &PolicyLayout, version: u32, slot: u32, obs_clip: f32) -> Self {
        let mut hidden = [0; MAX_HIDDEN];
        for (h, &w) in hidden.iter_mut().zip(&layout.hidden) {
            *h = w as u32;
        }
        Self {
            version,
            slot,
            obs_dim: layout.obs_dim as u32,
            act_dim: layout.act_dim as u32,
            n_hidden: layout.hidden.len().min(MAX_HIDDEN) as u32,
            hidden,
            obs_clip,
            updates: 0,
            env_steps: 0,
        }
    }

    pub fn layout(&self) -> PolicyLayout {
        let n = (self.n_hidden as usize).min(MAX_HIDDEN);
        PolicyLayout {
            obs_dim: self.obs_dim as usize,
            hidden: self.hidden[..n].iter().map(|&h| h as usize).collect(),
            act_dim: self.act_dim as usize,
        }
    }
}

// ---- sim → estimator, monitors: `telemetry` -------------------------------------------------

/// Header of one telemetry tick; the slice holds one [`EnvTick`] per env.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.TickHeader.v1")]
pub struct TickHeader {
    pub tick: u64,
    /// Environment steps so far (ticks × envs).
    pub env_steps: u64,
    pub policy_version: u32,
    pub envs: u32,
    /// Completed episodes and successes so far, over all envs.
    pub episodes: u64,
    pub successes: u64,
}

/// Episode event bits of [`EnvTick::events`].
pub const EVENT_TERMINATED: u8 = 1;
pub const EVENT_TRUNCATED: u8 = 2;
pub const EVENT_SUCCESS: u8 = 4;
pub const EVENT_FAULT: u8 = 8;

/// One env at one tick.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.EnvTick.v1")]
pub struct EnvTick {
    pub env: u32,
    /// True area (0 flat, 1 rough).
    pub area: u8,
    /// Bits `EVENT_*`.
    pub events: u8,
    /// Policy slot that acted.
    pub slot: u8,
    pub _reserved: u8,
    /// Chassis position, metres.
    pub pos: [f32; 3],
    /// Unity Euler angles (θx, θy, θz), radians.
    pub euler: [f32; 3],
    /// sin θx (SPEC S7's signal).
    pub sin_pitch: f32,
    pub reward: f32,
}

// ---- estimator → sim, monitors: `terrain` ---------------------------------------------------

/// Header of one terrain estimate; the slice holds one [`TerrainEstimate`] per env.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.TerrainHeader.v1")]
pub struct TerrainHeader {
    /// The telemetry tick this estimate answers.
    pub tick: u64,
    /// Estimates so far that had a class, and how many matched the true area (scoring only:
    /// the estimator never trains on labels).
    pub scored: u64,
    pub correct: u64,
    pub envs: u32,
    /// Mixture refits so far.
    pub refits: u32,
}

/// Class value before enough ticks have been seen.
pub const CLASS_UNKNOWN: u8 = u8::MAX;

/// The estimator's view of one env.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.TerrainEstimate.v1")]
pub struct TerrainEstimate {
    pub env: u32,
    /// Most probable class (0 = lowest mean = flat), or [`CLASS_UNKNOWN`].
    pub class: u8,
    pub _reserved: [u8; 3],
    /// Posterior probability of `class`.
    pub posterior: f32,
    /// Rolling std of sin θx over the window.
    pub window_std: f32,
    /// Ticks in the window so far.
    pub window: u32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    const MSG: &str = "layout changed: bump the version in the type name";

    #[test]
    fn rollout_header_layout() {
        assert_eq!(
            (size_of::<RolloutHeader>(), align_of::<RolloutHeader>()),
            (32, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(RolloutHeader, policy_version), 16, "{MSG}");
        assert_eq!(offset_of!(RolloutHeader, slot), 28, "{MSG}");
    }

    #[test]
    fn policy_header_layout_and_round_trip() {
        assert_eq!(
            (size_of::<PolicyHeader>(), align_of::<PolicyHeader>()),
            (56, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(PolicyHeader, hidden), 20, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, obs_clip), 36, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, updates), 40, "{MSG}");
        let l = PolicyLayout::new(10, &[128, 64], 2);
        assert_eq!(PolicyHeader::new(&l, 3, 1, 10.0).layout(), l);
    }

    #[test]
    fn telemetry_layouts() {
        assert_eq!(
            (size_of::<TickHeader>(), align_of::<TickHeader>()),
            (40, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(TickHeader, episodes), 24, "{MSG}");
        assert_eq!(
            (size_of::<EnvTick>(), align_of::<EnvTick>()),
            (40, 4),
            "{MSG}"
        );
        assert_eq!(offset_of!(EnvTick, pos), 8, "{MSG}");
        assert_eq!(offset_of!(EnvTick, sin_pitch), 32, "{MSG}");
    }

    #[test]
    fn terrain_layouts() {
        assert_eq!(
            (size_of::<TerrainHeader>(), align_of::<TerrainHeader>()),
            (32, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(TerrainHeader, envs), 24, "{MSG}");
        assert_eq!(
            (size_of::<TerrainEstimate>(), align_of::<TerrainEstimate>()),
            (20, 4),
            "{MSG}"
        );
        assert_eq!(offset_of!(TerrainEstimate, posterior), 8, "{MSG}");
    }
}
