//! What the recording logs of one env at one tick, from either source: the live
//! `telemetry`/`terrain` services or a telemetry CSV. One type each, so the logging code
//! does not care where the data came from.

use common::TelemetryRow;
use common::wire::{self, EnvTick, TerrainEstimate};

/// One robot at one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotSample {
    pub env: usize,
    /// Chassis position, metres (Y up).
    pub pos: [f64; 3],
    /// Unity Euler angles (θx, θy, θz), radians.
    pub euler: [f64; 3],
    pub sin_pitch: f64,
    pub reward: f64,
    /// The episode ended on this tick (terminated, truncated or a fault): the robot starts
    /// elsewhere on the next, so its trail starts over.
    pub episode_end: bool,
    /// The target on the ground (x, z), metres, when the source carries it.
    pub target: Option<[f64; 2]>,
}

impl From<&EnvTick> for RobotSample {
    fn from(t: &EnvTick) -> Self {
        let ends = wire::EVENT_TERMINATED | wire::EVENT_TRUNCATED | wire::EVENT_FAULT;
        Self {
            env: t.env as usize,
            pos: t.pos.map(f64::from),
            euler: t.euler.map(f64::from),
            sin_pitch: f64::from(t.sin_pitch),
            reward: f64::from(t.reward),
            episode_end: t.events & ends != 0,
            target: Some(t.target.map(f64::from)),
        }
    }
}

impl From<&TelemetryRow> for RobotSample {
    fn from(r: &TelemetryRow) -> Self {
        Self {
            env: r.env as usize,
            pos: [r.x, r.y, r.z],
            euler: [r.theta_x, r.theta_y, r.theta_z],
            sin_pitch: r.sin_pitch,
            reward: r.reward,
            episode_end: r.terminated || r.truncated,
            target: Some([r.target_x, r.target_z]),
        }
    }
}

/// The estimator's view of one env at one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimateSample {
    pub env: usize,
    /// The most probable class (0 flat, 1 rough), or `None` before the estimator knows.
    pub class: Option<u8>,
    /// Posterior probability of `class` (0 while unknown).
    pub posterior: f64,
    /// Rolling std of sin θx over the estimator's window (0 until it has one).
    pub window_std: f64,
}

impl From<&TerrainEstimate> for EstimateSample {
    fn from(e: &TerrainEstimate) -> Self {
        Self {
            env: e.env as usize,
            class: (e.class != wire::CLASS_UNKNOWN).then_some(e.class),
            posterior: f64::from(e.posterior),
            window_std: f64::from(e.window_std),
        }
    }
}
