//! The recording's entity paths and timeline, in one place: the logging code and whoever
//! reads a recording back use the same names.
//!
//! The world is Y up, right-handed, metres (the sim's frame). A robot's pose is the
//! transform of `world/robots/<env>`, so its marker and body (logged once, static) move with
//! it; trails and targets are in world coordinates, outside the robot's subtree.

/// The sequence timeline: the sim's tick (the telemetry header's `tick`, or the CSV's).
pub const TIMELINE: &str = "tick";
/// Root of the 3-D scene; carries the view coordinates.
pub const WORLD: &str = "world";
/// The floor mesh (static).
pub const TERRAIN: &str = "world/terrain";

/// One time series per metric; each holds one series per env (the batch index is the env).
pub const SIN_PITCH: &str = "metrics/sin_pitch";
pub const WINDOW_STD: &str = "metrics/window_std";
pub const CLASS: &str = "metrics/class";
pub const POSTERIOR: &str = "metrics/posterior";
pub const REWARD: &str = "metrics/reward";
/// Every metric entity, in logging order.
pub const METRICS: [&str; 5] = [SIN_PITCH, WINDOW_STD, CLASS, POSTERIOR, REWARD];

/// The robot of env `env`: its pose (a transform per logged tick) and its marker.
pub fn robot(env: usize) -> String {
    format!("world/robots/{env}")
}

/// The chassis box of env `env`'s robot, in the robot's frame (static).
pub fn body(env: usize) -> String {
    format!("world/robots/{env}/body")
}

/// The recent positions of env `env`'s robot, as a line strip in world coordinates.
pub fn trail(env: usize) -> String {
    format!("world/trails/{env}")
}

/// The target of env `env`'s robot, a point on the ground (only where targets are known).
pub fn target(env: usize) -> String {
    format!("world/targets/{env}")
}
