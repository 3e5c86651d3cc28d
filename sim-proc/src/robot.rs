//! The two-wheeled differential robot in one rapier world (SPEC S2).
//!
//! Body frame: X through the wheel axle (the left wheel at +X), Y up, Z forward. The chassis
//! body's origin is the axle's midpoint. A passive low-friction ball (skid) under the rear
//! keeps it level. The wheels come in two models (`sim.robot.wheel-model`):
//!
//! - `joint`: each wheel is a body on a revolute impulse joint about X with a velocity motor.
//!   Impulse joints, not a multibody: rapier rebuilds a multibody's dense mass matrix every
//!   solver substep, which took 60 % of a rough-ground step and doubled its cost. The price is
//!   a little joint compliance: wheel and chassis part by 0.3 mm at rest and by under 2 mm on
//!   hard landings on rough ground; the physics tests hold with either.
//! - `contact`: each wheel is a collider on the chassis, and the physics hook [`Drive`] gives
//!   its ground contacts the surface velocity a wheel turning at the command would have, so
//!   friction pushes the robot as a rolling wheel does. One body per robot and no joints; the
//!   wheels have no inertia of their own and no torque limit (friction is the only limit).

use common::config::{RobotConfig, WheelModel, WheelShape};
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
    /// The chassis box's collider.
    body: ColliderHandle,
    /// The skid ball's collider.
    caster: ColliderHandle,
    /// Wheel colliders, left (+X) then right (−X).
    wheels: [ColliderHandle; 2],
    /// The wheels' motorised joints, same order (`joint` model only).
    joints: Option<[ImpulseJointHandle; 2]>,
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
    let body = world.insert_collider(body, Some(chassis));
    let caster = ColliderBuilder::ball(cfg.caster_radius as f32)
        .translation(v3(caster_offset(cfg)))
        .mass(0.0)
        .friction(cfg.caster_friction as f32)
        .friction_combine_rule(CoefficientCombineRule::Min)
        .collision_groups(robot_groups());
    let caster = world.insert_collider(caster, Some(chassis));

    let half_track = 0.5 * cfg.track_width;
    let mut joints = [ImpulseJointHandle::invalid(); 2];
    let wheels = [0, 1].map(|side| {
        let x = if side == 0 { half_track } else { -half_track };
        let anchor = v3([x, 0.0, 0.0]);
        let mut shape = ColliderBuilder::new(wheel_shape(cfg));
        if cfg.wheel_shape == WheelShape::Cylinder {
            // parry's cylinders stand on Y: turn the axis onto X.
            shape = shape.rotation(Vector::new(0.0, 0.0, std::f32::consts::FRAC_PI_2));
        }
        let shape = shape
            .mass(cfg.wheel_mass as f32)
            .friction(cfg.wheel_friction as f32)
            .collision_groups(robot_groups());
        match cfg.wheel_model {
            WheelModel::Contact => world.insert_collider(
                shape
                    .translation(anchor)
                    .active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS),
                Some(chassis),
            ),
            WheelModel::Joint => {
                let wheel = world.insert_body(
                    RigidBodyBuilder::dynamic()
                        .pose(pose * Pose::from_translation(anchor))
                        .can_sleep(false),
                );
                let joint = RevoluteJointBuilder::new(Vector::X)
                    .local_anchor1(anchor)
                    .local_anchor2(Vector::ZERO)
                    .motor_velocity(0.0, cfg.motor_damping as f32)
                    .motor_max_force(cfg.motor_max_torque as f32);
                joints[side] = world.insert_impulse_joint(chassis, wheel, joint);
                world.insert_collider(shape, Some(wheel))
            }
        }
    });
    Robot {
        chassis,
        body,
        caster,
        wheels,
        joints: (cfg.wheel_model == WheelModel::Joint).then_some(joints),
    }
}

/// A wheel's shape (a cylinder standing on Y, as parry makes it).
fn wheel_shape(cfg: &RobotConfig) -> SharedShape {
    let r = cfg.wheel_radius as f32;
    match cfg.wheel_shape {
        WheelShape::Ball => SharedShape::ball(r),
        WheelShape::Cylinder => SharedShape::cylinder(0.5 * cfg.wheel_width as f32, r),
    }
}

impl Robot {
    /// Gives the built robot, where it stands, `cfg`'s chassis mass, wheel radius (the skid
    /// moved to stay level with the wheels) and torque limit, its chassis's centre of mass
    /// moved by `com_offset` (m, chassis frame) and a point mass of `payload` kg on top of the
    /// chassis: a world drawn by `[sim.randomize]`.
    pub fn refit(
        &self,
        world: &mut PhysicsWorld,
        cfg: &RobotConfig,
        com_offset: [f64; 3],
        payload: f64,
    ) {
        let he = cfg.chassis_half_extents;
        let volume = 8.0 * he[0] * he[1] * he[2];
        let mut mass = MassProperties::from_cuboid((cfg.chassis_mass / volume) as f32, v3(he));
        mass.local_com = v3(com_offset);
        world.colliders[self.body].set_mass_properties(mass);
        let [x, y, z] = chassis_offset(cfg);
        let top = v3([x, y + he[1], z]);
        world.bodies[self.chassis].set_additional_mass_properties(
            MassProperties::new(top, payload as f32, Vector::ZERO),
            true,
        );
        for wheel in self.wheels {
            world.colliders[wheel].set_shape(wheel_shape(cfg));
        }
        world.colliders[self.caster].set_translation_wrt_parent(v3(caster_offset(cfg)));
        for handle in self.joints.iter().flatten() {
            if let Some(j) = world.impulse_joints.get_mut(*handle, false) {
                j.data
                    .set_motor_max_force(JointAxis::AngX, cfg.motor_max_torque as f32);
            }
        }
    }

    /// World positions of the two wheel centres (left, right).
    pub fn wheel_centres(&self, world: &PhysicsWorld) -> [Vector; 2] {
        self.wheels.map(|h| world.colliders[h].translation())
    }

    /// Sets both wheels' friction (left, right): sand's sinkage (`sinkage`).
    pub fn set_wheel_friction(&self, world: &mut PhysicsWorld, friction: [f32; 2]) {
        for (h, mu) in self.wheels.iter().zip(friction) {
            world.colliders[*h].set_friction(mu);
        }
    }

    /// Commands both wheels' angular velocity (rad/s, already clipped) and returns the hook
    /// the physics steps until the next command run with. `joint` wheels take the command
    /// as their motors' target; `contact` wheels through the returned [`Drive`].
    pub fn command(&self, world: &mut PhysicsWorld, cfg: &RobotConfig, speeds: [f32; 2]) -> Drive {
        for (handle, speed) in self.joints.iter().flatten().zip(speeds) {
            if let Some(j) = world.impulse_joints.get_mut(*handle, false) {
                j.data
                    .set_motor_velocity(JointAxis::AngX, speed, cfg.motor_damping as f32);
            }
        }
        Drive {
            chassis: self.chassis,
            wheels: self.wheels,
            speeds,
        }
    }
}

/// The physics hook of `contact` wheels: each solver contact of a wheel with the ground gets
/// the velocity of that point of a wheel spinning at the command about the axle, relative to
/// the chassis. The solver then drives the contact's tangential slip to that velocity, within
/// the friction cone, as it would drive a turning wheel's contact point to rest on the ground.
/// Joint wheels carry no hook flag, so rapier never calls it for them.
pub struct Drive {
    chassis: RigidBodyHandle,
    wheels: [ColliderHandle; 2],
    speeds: [f32; 2],
}

impl PhysicsHooks for Drive {
    fn modify_solver_contacts(&self, ctx: &mut ContactModificationContext) {
        // The solver drives (v1 − v2)·t to −tangent_velocity·t: with the wheel first, the
        // tangent velocity is the surface velocity; with the wheel second, its negative.
        let Some((side, sign)) = (0..2).find_map(|side| {
            let h = self.wheels[side];
            (h == ctx.collider1)
                .then_some((side, 1.0))
                .or((h == ctx.collider2).then_some((side, -1.0)))
        }) else {
            return;
        };
        let axis = *ctx.bodies[self.chassis].rotation() * Vector::X;
        let spin = axis * (sign * self.speeds[side]);
        let centre = ctx.colliders[self.wheels[side]].translation();
        let Some(manifold) = ctx.rigid_mut() else {
            return;
        };
        for contact in manifold.solver_contacts.iter_mut() {
            let point = if sign > 0.0 {
                contact.anchor1
            } else {
                contact.anchor2
            };
            contact.tangent_velocity = spin.cross(point - centre);
        }
    }
}
