//! `[sim.robot]`: the two-wheeled differential robot's body, wheels and motors.

use super::ConfigError;
use super::range::invalid;
use super::setting::{Setting, choices, count, real, settings};
use serde::{Deserialize, Serialize};

/// Wheel collider shape: balls are 2–3× cheaper to collide with a heightfield (DESIGN §10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WheelShape {
    Ball,
    Cylinder,
}

impl Setting for WheelShape {}

/// How a wheel turns the robot's motion into ground contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WheelModel {
    /// Each wheel a body on a revolute joint with a velocity motor (torque-limited).
    Joint,
    /// Wheels fixed to the chassis whose ground contacts move at the commanded surface speed:
    /// no wheel bodies or joints, no wheel inertia and no torque limit (DESIGN §10).
    Contact,
}

impl Setting for WheelModel {}

settings! {
    /// The two-wheeled differential robot (SPEC S2).
    pub struct RobotConfig {
        /// Wheel radius (SPEC S2: ≈ 3–4 cm).
        pub wheel_radius: f64 = 0.035 => real(0.01, 0.2), "m", Advanced;
        /// Wheel width (cylinder wheels).
        pub wheel_width: f64 = 0.015 => real(0.002, 0.1), "m", Advanced;
        /// Distance between the wheel centres.
        pub track_width: f64 = 0.10 => real(0.03, 1.0), "m", Advanced;
        /// Wheel collider shape.
        pub wheel_shape: WheelShape = WheelShape::Ball => choices::<WheelShape>(), "", Advanced;
        /// How the wheels drive: `joint` (motorised wheel bodies) or `contact` (the ground
        /// contacts move at the wheels' surface speed).
        pub wheel_model: WheelModel = WheelModel::Joint => choices::<WheelModel>(), "", Advanced;
        /// Chassis box half extents (x across, y up, z along).
        pub chassis_half_extents: [f64; 3] = [0.035, 0.015, 0.05]
            => real(0.001, 1.0), "m", Advanced;
        /// Chassis mass.
        pub chassis_mass: f64 = 0.30 => real(1e-4, 100.0), "kg", Advanced;
        /// Mass of each wheel.
        pub wheel_mass: f64 = 0.03 => real(1e-4, 10.0), "kg", Advanced;
        /// Radius of the passive ball support (caster) at the rear; smaller than `wheel-radius`.
        pub caster_radius: f64 = 0.012 => real(0.002, 0.1), "m", Advanced;
        /// Ground friction coefficient of wheels.
        pub wheel_friction: f64 = 1.0 => real(0.0, 5.0), "", Advanced;
        /// Friction of the passive support (a low-friction skid).
        pub caster_friction: f64 = 0.05 => real(0.0, 5.0), "", Advanced;
        /// Wheel motor torque limit.
        pub motor_max_torque: f64 = 0.1 => real(1e-6, 10.0), "N·m", Advanced;
        /// Velocity motor gain of `joint` wheels (rapier acceleration-based damping, scaled by the
        /// wheel's own small inertia): at 10^5 the torque limit bounds the push and a robot climbs
        /// 12° at its command; 1000 stalls there at 1 rad/s (docs/RESULTS.md, R31).
        pub motor_damping: f64 = 1e5 => real(1e-6, 1e6), "", Advanced;
        /// Physics steps between a wheel command and the motors receiving it (a real robot's
        /// bus and controller delay; at the 1/30 s step, 3 is 100 ms). 0: at once, the paper's.
        pub command_latency: usize = 0 => count(0, 100), "physics steps", Advanced;
        /// Time constant of the motors' first-order response: each physics step the speed they
        /// drive at moves 1 - exp(-dt/τ) of the way to the command. 0: at once, the paper's.
        pub motor_time_constant: f64 = 0.0 => real(0.0, 10.0), "s", Advanced;
        /// Action clip: each wheel command in [-limit, limit] (SPEC S2).
        pub action_limit: f64 = 3.0 => real(1e-6, 100.0), "rad/s", Advanced;
        /// rapier's length unit (a robot this small halves its step cost at ≈ 0.2).
        pub length_unit: f64 = 0.2 => real(0.01, 10.0), "m", Advanced;
        /// rapier's solver substeps per physics step (each a velocity pass and
        /// `stabilization-iterations` passes); at 6, each is 5.6 ms of the default step.
        pub solver_iterations: usize = 6 => count(1, 16), "substeps", Advanced;
        /// rapier's stabilisation (relax) passes per solver substep: with 2, 4 substeps drive and
        /// climb as 6 with 1 do, for 6 % less physics (docs/RESULTS.md, R47).
        pub stabilization_iterations: usize = 1 => count(1, 8), "passes", Advanced;
    }
}

impl RobotConfig {
    /// The rules between fields (each field's own range is [`super::setting::Setting::check`]'s).
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        if self.caster_radius >= self.wheel_radius {
            return Err(invalid(
                "sim.robot.caster-radius",
                self.caster_radius,
                "must be smaller than wheel-radius",
            ));
        }
        Ok(())
    }
}
