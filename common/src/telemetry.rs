//! One row of per-tick telemetry, as `sim-proc --telemetry` writes it and the offline
//! analysis reads it. The CSV header is these field names; angles are radians.

use serde::{Deserialize, Serialize};

/// One env at one decision tick (`Default`: env 0 standing at the origin of flat ground).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TelemetryRow {
    /// Env index.
    pub env: u32,
    /// Decision tick of this env since the run started (0-based).
    pub tick: u64,
    /// True terrain under the robot: `flat` or `rough` (on the mixed course, the part it is on).
    pub area: crate::AreaKind,
    /// Episode counter of this env.
    pub episode: u64,
    /// Chassis position, metres (Y up).
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Unity-convention Euler angles of the chassis, radians in (-π, π]: pitch about the axle (X),
    /// yaw about up (Y), roll about the body's long axis (Z) (SPEC S2).
    pub theta_x: f64,
    pub theta_y: f64,
    pub theta_z: f64,
    /// sin θx, the classifier's input (SPEC S7).
    pub sin_pitch: f64,
    /// Wheel commands after clipping, rad/s.
    pub action_left: f64,
    pub action_right: f64,
    /// Reward earned on this tick.
    pub reward: f64,
    /// The episode ended in a terminal state on this tick (success or failure).
    pub terminated: bool,
    /// The episode was cut by the time limit or a fault on this tick (bootstrap the value).
    pub truncated: bool,
    /// The episode ended on this tick by reaching its target.
    pub success: bool,
    /// Target position on the ground, metres.
    pub target_x: f64,
    pub target_z: f64,
}
