//! `[sim.robot]`: the two-wheeled differential robot's body, wheels and motors.

use super::ConfigError;
use super::range::{count_in, in_range, invalid};
use serde::{Deserialize, Serialize};

/// Wheel collider shape: balls are 2–3× cheaper to collide with a heightfield (DESIGN §10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WheelShape {
    Ball,
    Cylinder,
}

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

/// The two-wheeled differential robot (SPEC S2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct RobotConfig {
    /// Wheel radius, metres. SPEC S2: ≈ 3–4 cm. [0.01, 0.2]. Default 0.035.
    pub wheel_radius: f64,
    /// Wheel width (cylinder wheels), metres. [0.002, 0.1]. Default 0.015.
    pub wheel_width: f64,
    /// Distance between the wheel centres, metres. [0.03, 1]. Default 0.10.
    pub track_width: f64,
    /// Wheel collider shape. Default `ball`.
    pub wheel_shape: WheelShape,
    /// How the wheels drive: `joint` (motorised wheel bodies) or `contact` (the ground
    /// contacts move at the wheels' surface speed). Default `joint`.
    pub wheel_model: WheelModel,
    /// Chassis box half extents (x across, y up, z along), metres. Default [0.035, 0.015, 0.05].
    pub chassis_half_extents: [f64; 3],
    /// Chassis mass, kg. (0, 100]. Default 0.30.
    pub chassis_mass: f64,
    /// Mass of each wheel, kg. (0, 10]. Default 0.03.
    pub wheel_mass: f64,
    /// Radius of the passive ball support (caster) at the rear, metres. [0.002, 0.1]. Default 0.012.
    pub caster_radius: f64,
    /// Ground friction coefficient of wheels. [0, 5]. Default 1.0.
    pub wheel_friction: f64,
    /// Friction of the passive support (a low-friction skid). [0, 5]. Default 0.05.
    pub caster_friction: f64,
    /// Wheel motor torque limit, N·m. (0, 10]. Default 0.1.
    pub motor_max_torque: f64,
    /// Velocity motor gain of `joint` wheels (rapier acceleration-based damping, scaled by the
    /// wheel's own small inertia): at 10^5 the torque limit bounds the push and a robot climbs
    /// 12° at its command; 1000 stalls there at 1 rad/s (docs/RESULTS.md, R31). (0, 10^6]. Default 10^5.
    pub motor_damping: f64,
    /// Action clip: each wheel command in [-limit, limit] rad/s (SPEC S2). (0, 100]. Default 3.0.
    pub action_limit: f64,
    /// rapier's length unit, metres (a robot this small halves its step cost at ≈ 0.2). [0.01, 10]. Default 0.2.
    pub length_unit: f64,
    /// rapier's solver substeps per physics step (each a velocity pass and `stabilization-iterations` passes). 1 ..= 16. Default 6 (5.6 ms each at the default step).
    pub solver_iterations: usize,
    /// rapier's stabilisation (relax) passes per solver substep: with 2, 4 substeps drive and
    /// climb as 6 with 1 do, for 6 % less physics (docs/RESULTS.md, R47). 1 ..= 8. Default 1.
    pub stabilization_iterations: usize,
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            wheel_radius: 0.035,
            wheel_width: 0.015,
            track_width: 0.10,
            wheel_shape: WheelShape::Ball,
            wheel_model: WheelModel::Joint,
            chassis_half_extents: [0.035, 0.015, 0.05],
            chassis_mass: 0.30,
            wheel_mass: 0.03,
            caster_radius: 0.012,
            wheel_friction: 1.0,
            caster_friction: 0.05,
            motor_max_torque: 0.1,
            motor_damping: 1e5,
            action_limit: 3.0,
            length_unit: 0.2,
            solver_iterations: 6,
            stabilization_iterations: 1,
        }
    }
}

impl RobotConfig {
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        in_range("sim.robot.wheel-radius", self.wheel_radius, 0.01, 0.2)?;
        in_range("sim.robot.wheel-width", self.wheel_width, 0.002, 0.1)?;
        in_range("sim.robot.track-width", self.track_width, 0.03, 1.0)?;
        for v in self.chassis_half_extents {
            in_range("sim.robot.chassis-half-extents", v, 0.001, 1.0)?;
        }
        in_range("sim.robot.chassis-mass", self.chassis_mass, 1e-4, 100.0)?;
        in_range("sim.robot.wheel-mass", self.wheel_mass, 1e-4, 10.0)?;
        in_range("sim.robot.caster-radius", self.caster_radius, 0.002, 0.1)?;
        in_range("sim.robot.wheel-friction", self.wheel_friction, 0.0, 5.0)?;
        in_range("sim.robot.caster-friction", self.caster_friction, 0.0, 5.0)?;
        in_range(
            "sim.robot.motor-max-torque",
            self.motor_max_torque,
            1e-6,
            10.0,
        )?;
        in_range("sim.robot.motor-damping", self.motor_damping, 1e-6, 1e6)?;
        in_range("sim.robot.action-limit", self.action_limit, 1e-6, 100.0)?;
        in_range("sim.robot.length-unit", self.length_unit, 0.01, 10.0)?;
        count_in("sim.robot.solver-iterations", self.solver_iterations, 1, 16)?;
        count_in(
            "sim.robot.stabilization-iterations",
            self.stabilization_iterations,
            1,
            8,
        )?;
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
