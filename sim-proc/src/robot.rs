//! The two-wheeled differential robot in one rapier world (SPEC S2).
//!
//! Body frame: X through the wheel axle (the left wheel at +X), Y up, Z forward. The chassis
//! body's origin is the axle's midpoint. Each wheel is a body on a revolute impulse joint about
//! X with a velocity motor; a passive low-friction ball (skid) under the rear keeps it level.
//!
//! Impulse joints, not a multibody: rapier rebuilds a multibody's dense mass matrix every
//! solver substep, which took 60 % of a rough-ground step and doubled its cost. The price is
//! a little joint compliance: wheel and chassis part by 0.3 mm at rest and by under 2 mm on
//! hard landings on rough ground; the physics tests hold with either.

use common::config::{RobotConfig, WheelShape};
use rapier3d::prelude::*;

/// Collision group of the terrain; robot parts collide with it only, never with each other.
pub const TERRAIN_GROUP: Group = Group::GROUP_1;
pub const ROBOT_GROUP: Group = Group::GROUP_2;

/// The chassis collider's centre relative to the axle (a little up and rearward).
pub fn chassis_offset(cfg: &RobotConfig) -> [f64; 3] {
    let [_, hy, hz] = cfg.chassis_half_extents;
    [0.0, hy - 0.01, 0.03 - hz]
}

/// Where the skid ball sits relative to the axle: at the rear, its bottom level with the wheels'.
pub fn caster_offset(cfg: &RobotConfig) -> [f64; 3] {
    let hz = cfg.chassis_half_extents[2];
    [
        0.0,
        -(cfg.wheel_radius - cfg.caster_radius),
        chassis_offset(cfg)[2] - hz + cfg.caster_radius,
    ]
}

/// Handles of one robot's parts.
#[derive(Debug, Clone, Copy)]
pub struct Robot {
    pub chassis: RigidBodyHandle,
    /// Wheel joints, left (+X) then right (−X).
    pub wheels: [ImpulseJointHandle; 2],
    /// Wheel bodies, same order.
    pub wheel_bodies: [RigidBodyHandle; 2],
}

fn v3(a: [f64; 3]) -> Vector {
    Vector::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

fn robot_groups() -> InteractionGroups {
    InteractionGroups::new(ROBOT_GROUP, TERRAIN_GROUP, InteractionTestMode::And)
}

/// Builds the robot with its axle midpoint at `pose`.
pub fn build(world: &mut PhysicsWorld, cfg: &RobotConfig, pose: Pose) -> Robot {
    let he = cfg.chassis_half_extents;
    let chassis = world.insert_body(RigidBodyBuilder::dynamic().pose(pose).can_sleep(false));
    let body = ColliderBuilder::cuboid(he[0] as f32, he[1] as f32, he[2] as f32)
        .translation(v3(chassis_offset(cfg)))
        .mass(cfg.chassis_mass as f32)
        .collision_groups(robot_groups());
    world.insert_collider(body, Some(chassis));
    let caster = ColliderBuilder::ball(cfg.caster_radius as f32)
        .translation(v3(caster_offset(cfg)))
        .mass(0.0)
        .friction(cfg.caster_friction as f32)
        .friction_combine_rule(CoefficientCombineRule::Min)
        .collision_groups(robot_groups());
    world.insert_collider(caster, Some(chassis));

    let half_track = 0.5 * cfg.track_width;
    let mut wheel_bodies = [chassis; 2];
    let wheels = [0, 1].map(|side| {
        let x = if side == 0 { half_track } else { -half_track };
        let anchor = v3([x, 0.0, 0.0]);
        let wheel = world.insert_body(
            RigidBodyBuilder::dynamic()
                .pose(pose * Pose::from_translation(anchor))
                .can_sleep(false),
        );
        wheel_bodies[side] = wheel;
        let r = cfg.wheel_radius as f32;
        let shape = match cfg.wheel_shape {
            WheelShape::Ball => ColliderBuilder::ball(r),
            // parry's cylinders stand on Y: turn the axis onto X.
            WheelShape::Cylinder => ColliderBuilder::cylinder(0.5 * cfg.wheel_width as f32, r)
                .rotation(Vector::new(0.0, 0.0, std::f32::consts::FRAC_PI_2)),
        };
        world.insert_collider(
            shape
                .mass(cfg.wheel_mass as f32)
                .friction(cfg.wheel_friction as f32)
                .collision_groups(robot_groups()),
            Some(wheel),
        );
        let joint = RevoluteJointBuilder::new(Vector::X)
            .local_anchor1(anchor)
            .local_anchor2(Vector::ZERO)
            .motor_velocity(0.0, cfg.motor_damping as f32)
            .motor_max_force(cfg.motor_max_torque as f32);
        world.insert_impulse_joint(chassis, wheel, joint)
    });
    Robot {
        chassis,
        wheels,
        wheel_bodies,
    }
}

/// Sets both wheels' target angular velocity (rad/s, already clipped).
pub fn set_wheel_speeds(
    world: &mut PhysicsWorld,
    robot: &Robot,
    cfg: &RobotConfig,
    speeds: [f32; 2],
) {
    for (handle, speed) in robot.wheels.iter().zip(speeds) {
        if let Some(j) = world.impulse_joints.get_mut(*handle, false) {
            j.data
                .set_motor_velocity(JointAxis::AngX, speed, cfg.motor_damping as f32);
        }
    }
}
