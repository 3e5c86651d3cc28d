//! Shared-memory message types (DESIGN §2), one section per direction. Every payload is
//! `repr(C)` with fixed-width fields and a versioned type name; slices carry the bulk data
//! and a user header carries the counters. Layout tests pin sizes and offsets.

use crate::config::PolicySlot;
use crate::policy::{MAX_HIDDEN, PolicyLayout};
use crate::{ACT_DIM, OBS_DIM};
use iceoryx2::prelude::ZeroCopySend;

// ---- sim → learner: `rollout` ---------------------------------------------------------------

/// Header of a rollout chunk. The slice holds `steps × envs` [`crate::Transition`]s in
/// `[step][env]` order, then `envs` more whose `obs` is each env's bootstrap observation.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.RolloutHeader.v3")]
pub struct RolloutHeader {
    /// Chunk sequence number from 0, per source; a gap means the learner missed chunks.
    pub chunk: u64,
    /// Environment steps the sim has taken in total, including this chunk.
    pub env_steps: u64,
    /// Decision steps per env in the chunk (T), and envs (N): the slice holds T × N
    /// transitions, then N bootstrap observations. Each transition carries the version and
    /// slot of the policy that acted.
    pub steps: u32,
    pub envs: u32,
    /// The sim that produced the chunk: its host's source id (`lavatube join --source`), 0
    /// for the sim beside the learner. Chunk ids and env ids count per source.
    pub source: u32,
    pub _reserved: u32,
}

// ---- learner → sim: `policy` ----------------------------------------------------------------

/// Header of a policy message; the slice is the flat actor in `crate::policy`'s layout.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.PolicyHeader.v3")]
pub struct PolicyHeader {
    /// Per slot, continued across learner restarts and swaps (the new learner resumes the
    /// newest checkpoint, which is taken before each publish).
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
    /// Rollout chunks of the current sim this learner has consumed: the id of the last one
    /// plus 1, 0 before the first. A sync-mode sim waits for this to pass its last chunk.
    pub chunks_seen: u64,
    /// Process id of the publishing learner: a new one means a restarted or swapped learner,
    /// whose current policy a waiting sync-mode sim takes instead of waiting for a chunk it
    /// may never have received.
    pub learner: u32,
    /// Checkpoint and metrics writes this learner process could not make (a full disk):
    /// training went on, and the launcher reports the count in `summary.json`.
    pub write_failures: u32,
}

/// The widest hidden layer a policy header may name (the config allows 4096): anything
/// wider is no learner's, and its size would overflow the layout arithmetic.
const MAX_POLICY_WIDTH: u32 = 1 << 16;

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
            chunks_seen: 0,
            learner: std::process::id(),
            write_failures: 0,
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

    /// Why a policy message for `slot` must be refused, if it must: a shape no sim can act
    /// with, another slot's header, weights of the wrong length, or a non-finite weight.
    pub fn refusal(&self, slot: PolicySlot, weights: &[f32]) -> Option<&'static str> {
        let n = (self.n_hidden as usize).min(self.hidden.len());
        if self.obs_dim as usize != OBS_DIM
            || self.act_dim as usize != ACT_DIM
            || n == 0
            || self.hidden[..n]
                .iter()
                .any(|&w| w == 0 || w > MAX_POLICY_WIDTH)
        {
            return Some("wrong shape");
        }
        if self.slot != slot.index() as u32 {
            return Some("another slot's policy");
        }
        if weights.len() != self.layout().len() {
            return Some("wrong length");
        }
        if !self.obs_clip.is_finite() || !weights.iter().all(|w| w.is_finite()) {
            return Some("non-finite weights");
        }
        None
    }
}

// ---- sim → estimator, monitors: `telemetry` -------------------------------------------------

/// Header of one telemetry tick; the slice holds one [`EnvTick`] per env.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.TickHeader.v2")]
pub struct TickHeader {
    pub tick: u64,
    /// Environment steps so far (ticks × envs).
    pub env_steps: u64,
    pub policy_version: u32,
    pub envs: u32,
    /// Completed episodes and successes so far, over all envs.
    pub episodes: u64,
    pub successes: u64,
    /// When the sim sent the tick, [`monotonic_ns`]: readers on the same host subtract it from
    /// their own clock to measure transport latency (`lavatube bench`).
    pub sent_ns: u64,
    /// Sum over successful episodes of their length in ticks, and of its square: the mean
    /// and std of the reach time (SPEC S8's Table 1) without recording every episode.
    pub reach_ticks: u64,
    pub reach_ticks_sq: u64,
}

/// The send-timestamp clock of [`TickHeader::sent_ns`]: `CLOCK_MONOTONIC`, the one clock
/// every process on a host shares.
pub use crate::clock::monotonic_ns;

/// Episode event bits of [`EnvTick::events`].
pub const EVENT_TERMINATED: u8 = 1;
pub const EVENT_TRUNCATED: u8 = 2;
pub const EVENT_SUCCESS: u8 = 4;
pub const EVENT_FAULT: u8 = 8;
/// The ending put the robot somewhere new (a respawn or a course's next leg): the tick's pose
/// does not follow from the last tick's.
pub const EVENT_PLACED: u8 = 16;

/// One env at one tick.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.EnvTick.v4")]
pub struct EnvTick {
    pub env: u32,
    /// True terrain under the robot (`AreaKind::code`): the env's area, or on the mixed course
    /// the part it is on.
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
    /// The episode's target on the ground (x, z), metres; on an ending tick, the ended one's.
    pub target: [f32; 2],
    /// The IMU's orientation filter's Euler angles, as `euler`; NaN when the sim runs no IMU
    /// (`SimConfig::simulates_imu`).
    pub imu_euler: [f32; 3],
    /// sin of `imu_euler`'s θx: the estimator's signal with `estimator.signal = "imu"`.
    pub imu_sin_pitch: f32,
    /// The wheel commands (left, right) the step ran with, after clipping, rad/s: the slip
    /// feature's commanded path.
    pub command: [f32; 2],
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

// ---- learner host's bridge → `lavatube status`: `hosts` -----------------------------------

/// Header of the sim hosts a learner host hears (DESIGN §9); the slice holds one
/// [`SimHost`] per source seen.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.HostsHeader.v1")]
pub struct HostsHeader {
    /// When the bridge wrote it, [`monotonic_ns`].
    pub sent_ns: u64,
    pub hosts: u32,
    pub _reserved: u32,
}

/// One sim host as the learner host's bridge sees it.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.SimHost.v1")]
pub struct SimHost {
    /// Its source id (`lavatube join --source`).
    pub source: u32,
    /// 1 while its Zenoh liveliness token is alive, 0 once it is gone.
    pub joined: u32,
    /// Rollout chunks received from it, and the id of the last one.
    pub chunks: u64,
    pub last_chunk: u64,
    /// Env steps its sim has taken, as its last chunk says.
    pub env_steps: u64,
    /// Frames missing from its sequence.
    pub lost: u64,
    /// Over the last second.
    pub steps_per_s: f32,
    pub bytes_per_s: f32,
}

// ---- gym client ↔ sim: `gym/act`, `gym/step` (`sim.acting = "external"`) ------------------

/// [`GymStepHeader::command`] of the sim's first message, before any request: it is ready.
/// (`gym/step` keeps its newest message for a client that connects later, so a new client
/// reads the envs and the action limit from whatever the sim sent last.)
pub const GYM_READY: u32 = 0;
/// [`GymActHeader::command`]: step every env with the slice's actions.
pub const GYM_STEP: u32 = 1;
/// [`GymActHeader::command`]: start every env's episode over (seeded with [`GYM_SEEDED`]).
pub const GYM_RESET: u32 = 2;
/// [`GymActHeader::command`]: the client leaves.
pub const GYM_CLOSE: u32 = 3;
/// [`GymActHeader::flags`] bit: rebuild every env from [`GymActHeader::seed`].
pub const GYM_SEEDED: u32 = 1;
/// [`GymStepHeader::status`]: the request was carried out.
pub const GYM_OK: u32 = 0;
/// [`GymStepHeader::status`]: the request was refused (the sim's log says why); nothing moved.
pub const GYM_REFUSED: u32 = 1;

/// A gym client's request. For [`GYM_STEP`] the slice holds `envs × ACT_DIM` wheel
/// commands in `[env][wheel]` order (left, right), rad/s; otherwise it is empty.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.GymActHeader.v1")]
pub struct GymActHeader {
    /// The client's number for this request; the answer carries it back.
    pub request: u64,
    /// The seed of a [`GYM_RESET`] with [`GYM_SEEDED`].
    pub seed: u64,
    /// [`GYM_STEP`], [`GYM_RESET`] or [`GYM_CLOSE`].
    pub command: u32,
    /// Bits [`GYM_SEEDED`].
    pub flags: u32,
}

/// The sim's answer to a [`GymActHeader`], or its [`GYM_READY`]: the slice holds one
/// [`GymEnvStep`] per env after a reset or a step (none otherwise).
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.GymStepHeader.v1")]
pub struct GymStepHeader {
    /// The request answered.
    pub request: u64,
    /// Decision steps since the client's last reset.
    pub tick: u64,
    /// Env steps the sim has taken in this run (ticks × envs).
    pub env_steps: u64,
    pub envs: u32,
    /// The command answered.
    pub command: u32,
    /// [`GYM_OK`] or [`GYM_REFUSED`].
    pub status: u32,
    /// The bound of every wheel command, rad/s (SPEC S2's action space is ± this).
    pub action_limit: f32,
}

/// One env after a reset or a step. An episode that ended in the step has already been
/// replaced by the next one (Gymnasium's same-step autoreset): `obs` is the new episode's
/// first observation and `final_obs` the ended one's last.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.GymEnvStep.v1")]
pub struct GymEnvStep {
    /// SPEC S5's observation.
    pub obs: [f32; OBS_DIM],
    /// The last observation of the episode that ended in this step (zeros otherwise, and
    /// after a physics fault).
    pub final_obs: [f32; OBS_DIM],
    /// SPEC S4's reward of the step (0 after a reset).
    pub reward: f32,
    /// Decision steps of the episode the step belonged to, this one included.
    pub episode_steps: u32,
    /// 1 when the episode ended in a terminal state (target reached, too far from it, tipped
    /// over, left the area, stalled).
    pub terminated: u8,
    /// 1 when the episode was cut short (time limit, physics fault): bootstrap its value.
    pub truncated: u8,
    /// 1 when the episode ended at its target.
    pub success: u8,
    /// The ground under the robot: `AreaKind::code`.
    pub area: u8,
    pub env: u32,
}

// ---- `lavatube swap-learner` → launcher: `swap` (request-response) --------------------------

/// Bytes of a path in a [`SwapRequest`].
pub const SWAP_PATH_BYTES: usize = 1024;
/// Bytes of a [`SwapReply`] message.
pub const SWAP_MESSAGE_BYTES: usize = 512;

/// Replace the run's learner: with a new config (only its `[ppo]` section may differ from the
/// running one's) and/or starting from a named checkpoint. Empty strings mean "unchanged" and
/// "the run's newest checkpoint". Paths are absolute, UTF-8.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.SwapRequest.v1")]
pub struct SwapRequest {
    pub config_len: u32,
    pub checkpoint_len: u32,
    /// The policy slot whose learner to replace (`PolicySlot::index`).
    pub slot: u32,
    pub _reserved: u32,
    pub config: [u8; SWAP_PATH_BYTES],
    pub checkpoint: [u8; SWAP_PATH_BYTES],
}

impl Default for SwapRequest {
    fn default() -> Self {
        Self {
            config_len: 0,
            checkpoint_len: 0,
            slot: 0,
            _reserved: 0,
            config: [0; SWAP_PATH_BYTES],
            checkpoint: [0; SWAP_PATH_BYTES],
        }
    }
}

impl SwapRequest {
    /// A request; fails naming the path that does not fit.
    pub fn new(slot: u32, config: &str, checkpoint: &str) -> Result<Self, String> {
        let mut r = Self {
            slot,
            ..Self::default()
        };
        r.config_len = put_str("config path", config, &mut r.config)?;
        r.checkpoint_len = put_str("checkpoint path", checkpoint, &mut r.checkpoint)?;
        Ok(r)
    }

    pub fn config(&self) -> String {
        get_str(&self.config, self.config_len)
    }

    pub fn checkpoint(&self) -> String {
        get_str(&self.checkpoint, self.checkpoint_len)
    }
}

/// The launcher's answer to a [`SwapRequest`], sent once the swap is done or refused.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lavatube.SwapReply.v1")]
pub struct SwapReply {
    /// 1 when the new learner runs, 0 when the swap was refused (the old one still runs).
    pub ok: u32,
    pub len: u32,
    pub message: [u8; SWAP_MESSAGE_BYTES],
}

impl Default for SwapReply {
    fn default() -> Self {
        Self {
            ok: 0,
            len: 0,
            message: [0; SWAP_MESSAGE_BYTES],
        }
    }
}

impl SwapReply {
    /// A reply; a message longer than [`SWAP_MESSAGE_BYTES`] is cut at a character boundary.
    pub fn new(ok: bool, message: &str) -> Self {
        let mut end = message.len().min(SWAP_MESSAGE_BYTES);
        while !message.is_char_boundary(end) {
            end -= 1;
        }
        let mut r = Self {
            ok: u32::from(ok),
            ..Self::default()
        };
        r.len = put_str("message", &message[..end], &mut r.message).unwrap_or(0);
        r
    }

    pub fn message(&self) -> String {
        get_str(&self.message, self.len)
    }
}

fn put_str(what: &str, s: &str, buf: &mut [u8]) -> Result<u32, String> {
    let b = s.as_bytes();
    if b.len() > buf.len() {
        return Err(format!(
            "{what} is {} bytes; at most {} fit",
            b.len(),
            buf.len()
        ));
    }
    buf[..b.len()].copy_from_slice(b);
    Ok(b.len() as u32)
}

fn get_str(buf: &[u8], len: u32) -> String {
    String::from_utf8_lossy(&buf[..(len as usize).min(buf.len())]).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    const MSG: &str = "layout changed: bump the version in the type name";

    #[test]
    fn a_policy_no_sim_can_trust_is_refused_by_kind() {
        let layout = crate::PolicyLayout::new(OBS_DIM, &[4, 3], ACT_DIM);
        let h = PolicyHeader::new(&layout, 5, PolicySlot::Flat.index() as u32, 10.0);
        let w = vec![0.1f32; layout.len()];
        assert_eq!(h.refusal(PolicySlot::Flat, &w), None);
        assert_eq!(
            h.refusal(PolicySlot::Rough, &w),
            Some("another slot's policy")
        );
        assert_eq!(h.refusal(PolicySlot::Flat, &w[1..]), Some("wrong length"));
        let mut nan = w.clone();
        nan[7] = f32::NAN;
        assert_eq!(
            h.refusal(PolicySlot::Flat, &nan),
            Some("non-finite weights")
        );
        let clip = PolicyHeader {
            obs_clip: f32::INFINITY,
            ..h
        };
        assert_eq!(
            clip.refusal(PolicySlot::Flat, &w),
            Some("non-finite weights")
        );
        // Widths that would overflow the layout's size are refused before it is computed.
        let mut huge = h;
        huge.hidden[0] = u32::MAX;
        assert_eq!(huge.refusal(PolicySlot::Flat, &w), Some("wrong shape"));
        let empty = PolicyHeader { n_hidden: 0, ..h };
        assert_eq!(empty.refusal(PolicySlot::Flat, &w), Some("wrong shape"));
    }

    #[test]
    fn hosts_layout() {
        assert_eq!(
            (size_of::<HostsHeader>(), align_of::<HostsHeader>()),
            (16, 8),
            "{MSG}"
        );
        assert_eq!(
            (size_of::<SimHost>(), align_of::<SimHost>()),
            (48, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(SimHost, chunks), 8, "{MSG}");
        assert_eq!(offset_of!(SimHost, lost), 32, "{MSG}");
        assert_eq!(offset_of!(SimHost, bytes_per_s), 44, "{MSG}");
    }

    #[test]
    fn rollout_header_layout() {
        assert_eq!(
            (size_of::<RolloutHeader>(), align_of::<RolloutHeader>()),
            (32, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(RolloutHeader, steps), 16, "{MSG}");
        assert_eq!(offset_of!(RolloutHeader, envs), 20, "{MSG}");
        assert_eq!(offset_of!(RolloutHeader, source), 24, "{MSG}");
    }

    #[test]
    fn policy_header_layout_and_round_trip() {
        assert_eq!(
            (size_of::<PolicyHeader>(), align_of::<PolicyHeader>()),
            (72, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(PolicyHeader, hidden), 20, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, chunks_seen), 56, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, learner), 64, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, write_failures), 68, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, obs_clip), 36, "{MSG}");
        assert_eq!(offset_of!(PolicyHeader, updates), 40, "{MSG}");
        let l = PolicyLayout::new(10, &[128, 64], 2);
        assert_eq!(PolicyHeader::new(&l, 3, 1, 10.0).layout(), l);
    }

    #[test]
    fn telemetry_layouts() {
        assert_eq!(
            (size_of::<TickHeader>(), align_of::<TickHeader>()),
            (64, 8),
            "{MSG}"
        );
        assert_eq!(offset_of!(TickHeader, episodes), 24, "{MSG}");
        assert_eq!(offset_of!(TickHeader, sent_ns), 40, "{MSG}");
        assert_eq!(offset_of!(TickHeader, reach_ticks_sq), 56, "{MSG}");
        assert_eq!(
            (size_of::<EnvTick>(), align_of::<EnvTick>()),
            (72, 4),
            "{MSG}"
        );
        assert_eq!(offset_of!(EnvTick, command), 64, "{MSG}");
        assert_eq!(offset_of!(EnvTick, imu_euler), 48, "{MSG}");
        assert_eq!(offset_of!(EnvTick, pos), 8, "{MSG}");
        assert_eq!(offset_of!(EnvTick, sin_pitch), 32, "{MSG}");
        assert_eq!(offset_of!(EnvTick, target), 40, "{MSG}");
    }

    #[test]
    fn swap_messages_round_trip_and_refuse_long_paths() {
        let r = SwapRequest::new(1, "/runs/a/new.toml", "").expect("fits");
        assert_eq!(
            (r.config(), r.checkpoint()),
            ("/runs/a/new.toml".into(), String::new())
        );
        let long = "x".repeat(SWAP_PATH_BYTES + 1);
        assert_eq!(
            SwapRequest::new(0, "", &long).expect_err("too long"),
            "checkpoint path is 1025 bytes; at most 1024 fit"
        );
        let reply = SwapReply::new(true, &"é".repeat(SWAP_MESSAGE_BYTES));
        assert_eq!(reply.message().chars().count(), SWAP_MESSAGE_BYTES / 2);
        assert_eq!(size_of::<SwapRequest>(), 16 + 2 * SWAP_PATH_BYTES, "{MSG}");
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

    #[test]
    fn gym_layouts() {
        assert_eq!(
            (size_of::<GymActHeader>(), align_of::<GymActHeader>()),
            (24, 8),
            "{MSG}"
        );
        assert_eq!(
            (size_of::<GymStepHeader>(), align_of::<GymStepHeader>()),
            (40, 8),
            "{MSG}"
        );
        assert_eq!(
            (size_of::<GymEnvStep>(), align_of::<GymEnvStep>()),
            (96, 4),
            "{MSG}"
        );
        assert_eq!(offset_of!(GymEnvStep, reward), 80, "{MSG}");
        assert_eq!(offset_of!(GymEnvStep, terminated), 88, "{MSG}");
        assert_eq!(offset_of!(GymEnvStep, env), 92, "{MSG}");
    }
}
