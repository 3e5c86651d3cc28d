//! One environment: a rapier world holding the shared terrain and one robot, the paper's
//! episode bookkeeping, and the observation (SPEC S3–S5).

use crate::actuator::Actuator;
use crate::attitude::Sensing;
use crate::randomize::{Randomizer, WorldDraw};
use crate::robot::{self, Robot, TERRAIN_GROUP};
use crate::sinkage::Sinkage;
use crate::task::{self, Ending, Episode};
use crate::terrain::Terrain;
use common::config::{AreaKind, AttitudeSource, EpisodeStart, Rect, SimConfig, TerrainCollider};
use common::{OBS_DIM, Rng};
use glam::{EulerRot, Quat, Vec3};
use rapier3d::prelude::*;
use std::sync::Arc;

/// Height above the ground at which a robot is dropped when (re)spawned, metres.
const SPAWN_CLEARANCE: f64 = 0.003;

/// Env `id`'s course is drawn from random stream `COURSE_STREAMS + id` of the run seed, apart
/// from the streams its spawns and chained targets come from.
const COURSE_STREAMS: u64 = 1 << 32;

/// The terrain and its collider, built once and shared by every env.
#[derive(Clone)]
pub struct SharedTerrain {
    pub terrain: Arc<Terrain>,
    shape: SharedShape,
    centre: [f64; 3],
}

impl SharedTerrain {
    /// `terrain` with its collider shape of kind `collider` (`sim.terrain.collider`).
    pub fn new(terrain: Terrain, collider: TerrainCollider) -> Self {
        let (shape, centre) = crate::terrain::shape(&terrain, collider);
        Self {
            terrain: Arc::new(terrain),
            shape,
            centre,
        }
    }
}

/// Unity-convention Euler angles (SPEC S2): `q = Ry·Rx·Rz`, returned as (θx, θy, θz).
pub fn unity_euler(q: Quat) -> [f64; 3] {
    let (y, x, z) = q.to_euler(EulerRot::YXZ);
    [f64::from(x), f64::from(y), f64::from(z)]
}

/// Pose of the chassis as the task sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseState {
    pub pos: [f64; 3],
    pub rot: Quat,
    /// (θx, θy, θz), radians.
    pub euler: [f64; 3],
}

impl PoseState {
    pub fn ground(&self) -> [f64; 2] {
        [self.pos[0], self.pos[2]]
    }

    pub fn is_finite(&self) -> bool {
        self.pos.iter().all(rapier3d::math::ComplexField::is_finite) && self.rot.is_finite()
    }
}

/// What one decision step of one env produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo {
    pub reward: f64,
    pub ending: Option<Ending>,
    /// The observation of the state the episode ended in (before a new target was drawn):
    /// the value bootstrap target on truncation.
    pub final_obs: [f32; OBS_DIM],
    /// Number of physics faults (non-finite state) so far in this env.
    pub faults: u64,
    /// The target this step drove toward and the episode's steps including this one
    /// (read before a new episode replaces them).
    pub target: [f64; 2],
    pub episode_steps: u32,
    /// Whether the step's ending put the robot somewhere new (a respawn, or an evaluation
    /// course's next leg): its pose now does not follow from the last one.
    pub placed: bool,
}

/// One env: a physics world, a robot, an area and the current episode.
pub struct Env {
    pub id: usize,
    pub area: AreaKind,
    rect: Rect,
    cfg: SimConfig,
    terrain: SharedTerrain,
    world: PhysicsWorld,
    robot: Robot,
    pub episode: Episode,
    pub episode_index: u64,
    pub tick: u64,
    rng: Rng,
    /// Seeds leg k of an evaluation course (`EpisodeStart::Course`) as stream k.
    course_seed: u64,
    faults: u64,
    /// Worlds the robot has been placed in since the first.
    placements: u64,
    action: [f32; 2],
    /// The latency and lag between the clipped action and the wheels.
    actuator: Actuator,
    /// The IMU and its filter, when [`SimConfig::simulates_imu`].
    sensing: Option<Sensing>,
    /// The floor's friction and combine rule now (see [`floor_contact`]).
    contact: (f32, CoefficientCombineRule),
    /// The wheels' sinkage, when the world has sand.
    sinkage: Option<Sinkage>,
    /// Each episode's world and the observation noise, when `sim.randomize` draws any.
    randomizer: Option<Randomizer>,
}

impl Env {
    /// A new env at a random pose in its area with its first target (SPEC S3).
    pub fn new(id: usize, cfg: &SimConfig, terrain: &SharedTerrain, seed: u64) -> Self {
        let area = cfg.area_of(id);
        let rect = match area {
            AreaKind::Mixed => cfg.terrain.mixed_area,
            kind => cfg
                .terrain
                .area(kind)
                .expect("a validated config has an area for every kind with envs"),
        };
        let mut rng = Rng::derive(seed, id as u64);
        let (world, robot) = spawn(cfg, terrain, area, &rect, &mut rng);
        let mut env = Self {
            id,
            area,
            rect,
            cfg: cfg.clone(),
            terrain: terrain.clone(),
            world,
            robot,
            episode: Episode::new(&cfg.task, [0.0; 2], [0.0; 2]),
            episode_index: 0,
            tick: 0,
            rng,
            course_seed: Rng::derive(seed, COURSE_STREAMS + id as u64).next_u64(),
            faults: 0,
            placements: 0,
            action: [0.0; 2],
            actuator: Actuator::new(&cfg.robot, cfg.physics_dt),
            sensing: cfg
                .simulates_imu()
                .then(|| Sensing::new(&cfg.imu, cfg.gravity, seed, id)),
            contact: floor_contact(cfg, AreaKind::Flat),
            sinkage: None,
            randomizer: Randomizer::new(cfg, seed, id),
        };
        env.placed();
        env.new_episode();
        env
    }

    /// SPEC S3: later episodes start where the robot is, with a new target around it. On an
    /// evaluation course, leg k > 0 first places the robot at the last leg's target, and leg
    /// k's heading and target come from the course's stream k, whatever the policy did.
    fn new_episode(&mut self) {
        let mut leg = (self.cfg.task.episodes == EpisodeStart::Course)
            .then(|| Rng::derive(self.course_seed, self.episode_index));
        if let Some(leg) = leg.as_mut().filter(|_| self.episode_index > 0) {
            let yaw = leg.range(-std::f64::consts::PI, std::f64::consts::PI);
            let at = self.episode.target;
            let ground = ground_at(&self.cfg, self.area, at);
            let placed = build_world(&self.cfg, &self.terrain, at, yaw, ground);
            self.place(placed);
        }
        let start = self.pose().ground();
        let rng = leg.as_mut().unwrap_or(&mut self.rng);
        let target = task::draw_target(&self.cfg.task, &self.rect, start, rng);
        self.episode = Episode::new(&self.cfg.task, start, target);
        self.randomize();
    }

    /// Draws the new episode's world (`sim.randomize`) and gives it to the robot where it
    /// stands: its body, motors and sensors, gravity and the ground's friction.
    fn randomize(&mut self) {
        let Some(r) = self.randomizer.as_mut() else {
            return;
        };
        r.draw(self.episode_index, &mut self.cfg);
        let w = r.world;
        self.world.gravity = Vector::Y * -(w.gravity as f32);
        self.robot
            .refit(&mut self.world, &self.cfg.robot, w.com_offset, w.payload);
        self.actuator.retune(&self.cfg.robot, self.cfg.physics_dt);
        if let Some(s) = self.sensing.as_mut() {
            s.retune(&self.cfg.imu, w.gravity);
        }
        self.set_contact(self.contact_of(self.ground()));
    }

    /// The world episode `index` drew (or will draw), when `sim.randomize` draws any.
    pub fn world_of(&self, index: u64) -> Option<WorldDraw> {
        self.randomizer.as_ref().map(|r| r.world_of(index).0)
    }

    /// The kind of ground under the robot: the env's area, or on the mixed course whichever
    /// part of it the robot is on. What telemetry reports as the true label.
    pub fn ground(&self) -> AreaKind {
        ground_at(&self.cfg, self.area, self.pose().ground())
    }

    pub fn pose(&self) -> PoseState {
        let body = &self.world.bodies[self.robot.chassis];
        let t = body.translation();
        let rot = *body.rotation();
        PoseState {
            pos: [f64::from(t.x), f64::from(t.y), f64::from(t.z)],
            rot,
            euler: unity_euler(rot),
        }
    }

    /// World positions of the two wheel centres (left, right).
    pub fn wheel_centres(&self) -> [[f64; 3]; 2] {
        self.robot
            .wheel_centres(&self.world)
            .map(|t| [f64::from(t.x), f64::from(t.y), f64::from(t.z)])
    }

    /// The last clipped wheel command, rad/s.
    pub fn action(&self) -> [f32; 2] {
        self.action
    }

    /// Moves the env into a freshly built world and robot.
    /// Leaves the current episode unfinished and starts the next one from a random pose in
    /// the area, drawn as a respawning ending draws it (a gym client's reset).
    pub fn restart(&mut self) {
        self.respawn();
        self.episode_index += 1;
        self.new_episode();
    }

    /// A fresh world with the robot at a random pose in the area (SPEC S3).
    fn respawn(&mut self) {
        let placed = spawn(
            &self.cfg,
            &self.terrain,
            self.area,
            &self.rect,
            &mut self.rng,
        );
        self.place(placed);
    }

    fn place(&mut self, (world, robot): (PhysicsWorld, Robot)) {
        (self.world, self.robot) = (world, robot);
        self.placements += 1;
        self.placed();
    }

    /// On the mixed course, gives the floor the contact of the kind of ground under the robot
    /// (a slope's or gravel's friction) when that differs from the floor's. The whole floor
    /// takes it, so for the tick a robot straddles two kinds both wheels meet the one under
    /// its axle. An unchanged contact is left alone: touching the collider would reset its
    /// contacts' solver state.
    fn contact_ground(&mut self) {
        if self.area == AreaKind::Mixed {
            self.set_contact(self.contact_of(self.ground()));
        }
    }

    /// The floor's contact on ground of `kind` in this episode's world: [`floor_contact`],
    /// its friction times the kind's drawn factor when `sim.randomize` draws one.
    fn contact_of(&self, kind: AreaKind) -> (f32, CoefficientCombineRule) {
        let (mu, rule) = floor_contact(&self.cfg, kind);
        match &self.randomizer {
            Some(r) => ((f64::from(mu) * r.world.friction_of(kind)) as f32, rule),
            None => (mu, rule),
        }
    }

    /// Gives the floor `contact`, when it is not already the floor's.
    fn set_contact(&mut self, contact: (f32, CoefficientCombineRule)) {
        if contact == self.contact {
            return;
        }
        self.contact = contact;
        if let Some((_, floor)) = self
            .world
            .colliders
            .iter_mut()
            .find(|(_, c)| c.parent().is_none())
        {
            floor.set_friction(contact.0);
            floor.set_friction_combine_rule(contact.1);
        }
    }

    /// Sand: each wheel's sinkage over the decision step about to run at the command.
    fn sink(&mut self) {
        let Some(sinkage) = self.sinkage.as_mut() else {
            return;
        };
        let on_sand = self.robot.wheel_centres(&self.world).map(|c| {
            let at = [f64::from(c.x), f64::from(c.z)];
            ground_at(&self.cfg, self.area, at) == AreaKind::Sand
        });
        sinkage.step(
            &self.cfg.terrain.sand,
            &self.cfg.robot,
            (&mut self.world, &self.robot),
            self.action,
            on_sand,
            self.cfg.decision_dt(),
        );
    }

    /// The wheels' sinkage (left, right; `sinkage`): zero off sand.
    pub fn sinkage(&self) -> [f64; 2] {
        self.sinkage.map_or([0.0; 2], |s| s.depth)
    }

    /// Notes the new world's floor contact, starts its wheels unsunk and restarts the
    /// attitude filter on a robot just placed in it.
    fn placed(&mut self) {
        self.contact = floor_contact(&self.cfg, self.ground());
        self.sinkage =
            (self.cfg.terrain.rects_of(AreaKind::Sand).next().is_some()).then(Sinkage::default);
        self.actuator.reset();
        if let Some(s) = self.sensing.as_mut() {
            s.place(
                &self.world.bodies[self.robot.chassis],
                self.world.gravity,
                self.cfg.physics_dt,
            );
        }
    }

    /// The IMU filter's attitude (θx, θy, θz), when the env carries an IMU
    /// ([`SimConfig::simulates_imu`]).
    pub fn imu_euler(&self) -> Option<[f64; 3]> {
        self.sensing
            .as_ref()
            .map(|s| unity_euler(s.attitude().as_quat()))
    }

    /// The attitude the observation reports, (θx, θy, θz): the pose's, or with
    /// `sim.observation = "imu"` the IMU filter's.
    pub fn observed_euler(&self) -> [f64; 3] {
        match self.cfg.observation {
            AttitudeSource::Imu => self.imu_euler().unwrap_or_else(|| self.pose().euler),
            AttitudeSource::Truth => self.pose().euler,
        }
    }

    /// SPEC S5: target in the robot frame (3), its X-Z norm (1), cos/sin of θx, θy, θz (6).
    /// The target terms always use the true pose (localisation is out of scope); the
    /// attitude terms come from [`Env::observed_euler`].
    pub fn observe(&self) -> [f32; OBS_DIM] {
        let p = self.pose();
        let [tx, tz] = self.episode.target;
        let ty = self.terrain.terrain.height_at(tx, tz);
        let world_rel = Vec3::new(
            (tx - p.pos[0]) as f32,
            (ty - p.pos[1]) as f32,
            (tz - p.pos[2]) as f32,
        );
        let mut local = p.rot.inverse() * world_rel;
        let [mut ex, mut ey, mut ez] = self.observed_euler();
        if let Some(n) = self.randomizer.as_ref().and_then(|r| r.noise(self.tick)) {
            local += Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32);
            (ex, ey, ez) = (ex + n[3], ey + n[4], ez + n[5]);
        }
        [
            local.x,
            local.y,
            local.z,
            (local.x * local.x + local.z * local.z).sqrt(),
            ex.cos() as f32,
            ex.sin() as f32,
            ey.cos() as f32,
            ey.sin() as f32,
            ez.cos() as f32,
            ez.sin() as f32,
        ]
    }

    /// Runs the physics substeps. Returns false when the state went non-finite: rapier then
    /// quarantines the bodies. A panic inside rapier on a degenerate state is caught as well
    /// (the multibody wheels the robot first had did panic so); either way only this env's
    /// world is lost, and the caller respawns it.
    fn physics_substeps(&mut self) -> bool {
        let (world, sensing, actuator) = (&mut self.world, &mut self.sensing, &mut self.actuator);
        let (robot, cfg, action) = (&self.robot, &self.cfg, self.action);
        let (substeps, dt, chassis) = (cfg.substeps, cfg.physics_dt, robot.chassis);
        let stepped = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            // Ideal actuators take the command once per decision step, as the paper's.
            let mut drive = robot.command(world, &cfg.robot, actuator.apply(action));
            for step in 0..substeps {
                if step > 0 && !actuator.is_ideal() {
                    drive = robot.command(world, &cfg.robot, actuator.apply(action));
                }
                world.step_with_events(&drive, &());
                if !world.quarantine().is_empty() {
                    return false;
                }
                if let Some(s) = sensing.as_mut() {
                    s.sense(&world.bodies[chassis], world.gravity, dt);
                }
            }
            true
        }));
        stepped.unwrap_or(false)
    }

    /// Pushes the chassis when `sim.randomize` has a push due at this step of the episode.
    fn push(&mut self) {
        let steps = self.episode.steps;
        if let Some([x, z]) = self.randomizer.as_mut().and_then(|r| r.push(steps)) {
            let impulse = Vector::new(x as f32, 0.0, z as f32);
            self.world.bodies[self.robot.chassis].apply_impulse(impulse, true);
        }
    }

    /// One decision step: clip the action (SPEC S2), run the physics substeps, apply the
    /// episode rules, and start the next episode (respawning if the rules say so).
    pub fn step(&mut self, action: [f32; 2]) -> StepInfo {
        let placements = self.placements;
        let limit = self.cfg.robot.action_limit as f32;
        self.action = action.map(|a| {
            if a.is_finite() {
                a.clamp(-limit, limit)
            } else {
                0.0
            }
        });
        self.contact_ground();
        self.sink();
        self.push();
        let healthy = self.physics_substeps();
        self.tick += 1;
        let p = self.pose();
        let result = if healthy && p.is_finite() {
            let tip = self.cfg.task.tip_limit_deg.to_radians();
            let tipped = p.euler[0].abs() > tip || p.euler[2].abs() > tip;
            let left = !self
                .rect
                .contains(p.pos[0], p.pos[2], self.cfg.task.leave_margin);
            self.episode
                .step(&self.cfg.task, p.ground(), p.euler[0].cos(), tipped || left)
        } else {
            self.faults += 1;
            tracing::warn!(
                env = self.id,
                tick = self.tick,
                faults = self.faults,
                "non-finite physics state: respawning"
            );
            task::StepResult {
                reward: 0.0,
                ending: Some(Ending::Fault),
            }
        };
        let final_obs = if healthy && p.is_finite() {
            self.observe()
        } else {
            [0.0; OBS_DIM]
        };
        let (target, episode_steps) = (self.episode.target, self.episode.steps);
        if let Some(ending) = result.ending {
            if ending.respawns() && self.cfg.task.episodes == EpisodeStart::Chained {
                self.respawn();
            }
            self.episode_index += 1;
            self.new_episode();
        }
        StepInfo {
            reward: result.reward,
            ending: result.ending,
            final_obs,
            faults: self.faults,
            target,
            episode_steps,
            placed: self.placements != placements,
        }
    }
}

/// The kind of ground at `at` for an env in `area`: the area's own, or on the mixed course
/// the kind of the part there.
fn ground_at(cfg: &SimConfig, area: AreaKind, at: [f64; 2]) -> AreaKind {
    match area {
        AreaKind::Mixed => cfg.terrain.mixed_kind_at(at[0], at[1]),
        kind => kind,
    }
}

/// The floor's friction and combine rule on ground of `kind`: the paper's 1.0, averaged with
/// the wheel's, or the kind's own friction, of which a contact takes the lower with the
/// wheel's (the skid's `Min` rule keeps its own low friction either way).
fn floor_contact(cfg: &SimConfig, kind: AreaKind) -> (f32, CoefficientCombineRule) {
    match cfg.terrain.friction_of(kind) {
        Some(mu) => (mu as f32, CoefficientCombineRule::Min),
        None => (1.0, CoefficientCombineRule::Average),
    }
}

/// A fresh world with the shared terrain and a robot at a random pose inside `rect`, the
/// area of an env in `area`.
fn spawn(
    cfg: &SimConfig,
    terrain: &SharedTerrain,
    area: AreaKind,
    rect: &Rect,
    rng: &mut Rng,
) -> (PhysicsWorld, Robot) {
    let x = rng.range(rect.x[0], rect.x[1]);
    let z = rng.range(rect.z[0], rect.z[1]);
    let yaw = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
    build_world(cfg, terrain, [x, z], yaw, ground_at(cfg, area, [x, z]))
}

/// A world with the shared terrain, its contact that of `ground`, and the robot dropped at
/// ground point `at` facing `yaw`.
pub fn build_world(
    cfg: &SimConfig,
    terrain: &SharedTerrain,
    at: [f64; 2],
    yaw: f64,
    ground: AreaKind,
) -> (PhysicsWorld, Robot) {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::Y * -(cfg.gravity as f32);
    world.integration_parameters.dt = cfg.physics_dt as f32;
    world.integration_parameters.length_unit = cfg.robot.length_unit as f32;
    world.integration_parameters.num_solver_iterations = cfg.robot.solver_iterations;
    world
        .integration_parameters
        .num_internal_stabilization_iterations = cfg.robot.stabilization_iterations;
    let c = terrain.centre;
    let (friction, rule) = floor_contact(cfg, ground);
    world.insert_collider(
        ColliderBuilder::new(terrain.shape.clone())
            .translation(Vector::new(c[0] as f32, c[1] as f32, c[2] as f32))
            .friction(friction)
            .friction_combine_rule(rule)
            .collision_groups(InteractionGroups::new(
                TERRAIN_GROUP,
                robot::ROBOT_GROUP,
                InteractionTestMode::And,
            )),
        None,
    );
    let robot = robot::build(&mut world, &cfg.robot, drop_pose(cfg, terrain, at, yaw));
    (world, robot)
}

/// Where a robot placed at ground point `at` facing `yaw` starts: its axle just above the
/// highest ground under its footprint, so no part starts inside the floor.
pub fn drop_pose(cfg: &SimConfig, terrain: &SharedTerrain, at: [f64; 2], yaw: f64) -> Pose {
    let r = &cfg.robot;
    let reach = 0.5 * r.track_width + r.wheel_radius + 2.0 * r.chassis_half_extents[2];
    let mut ground = f64::MIN;
    for dx in [-reach, 0.0, reach] {
        for dz in [-reach, 0.0, reach] {
            ground = ground.max(terrain.terrain.height_at(at[0] + dx, at[1] + dz));
        }
    }
    Pose::from_parts(
        Vector::new(
            at[0] as f32,
            (ground + r.wheel_radius + SPAWN_CLEARANCE) as f32,
            at[1] as f32,
        ),
        Quat::from_rotation_y(yaw as f32),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controllers::{Controller, GoToController};
    use crate::terrain::Terrain;

    #[test]
    fn non_finite_physics_ends_the_episode_and_respawns_only_that_env() {
        let cfg = SimConfig {
            envs: [(AreaKind::Flat, 2)].into(),
            ..SimConfig::default()
        };
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut bad = Env::new(0, &cfg, &terrain, 1);
        let mut good = Env::new(1, &cfg, &terrain, 1);
        let episode = bad.episode_index;
        // Poison the chassis: a NaN velocity makes the next physics step non-finite.
        let chassis = bad.robot.chassis;
        bad.world.bodies[chassis].set_linvel(Vector::splat(f32::NAN), true);
        let info = bad.step([1.0, 1.0]);
        assert_eq!(info.ending, Some(Ending::Fault));
        assert!(
            info.ending
                .is_some_and(super::super::task::Ending::truncated),
            "a fault truncates, it does not terminate"
        );
        assert_eq!((info.faults, info.reward), (1, 0.0));
        assert_eq!(bad.episode_index, episode + 1);
        // Respawned inside its area with a finite pose, and it keeps running.
        let p = bad.pose();
        let flat = cfg.terrain.area(AreaKind::Flat).expect("default");
        assert!(p.is_finite() && flat.contains(p.pos[0], p.pos[2], 0.0));
        assert_eq!(bad.step([1.0, 1.0]).faults, 1);
        assert!(
            bad.observe()
                .iter()
                .all(rapier3d::math::ComplexField::is_finite)
        );
        // The other env never noticed.
        assert_eq!(good.step([1.0, 1.0]).faults, 0);
    }

    #[test]
    fn a_robot_that_stands_still_stalls_and_is_respawned_one_that_drives_does_not() {
        let mut cfg = SimConfig::default();
        cfg.task.stall_steps = 20;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut env = Env::new(0, &cfg, &terrain, 4);
        let spot = env.pose().pos;
        let infos: Vec<_> = (0..20).map(|_| env.step([0.0, 0.0])).collect();
        let endings: Vec<_> = infos.iter().map(|i| i.ending).collect();
        assert!(endings[..19].iter().all(Option::is_none), "{endings:?}");
        assert_eq!(endings[19], Some(Ending::Stalled));
        assert!(infos[19].placed && !infos[18].placed);
        let moved = env.pose().pos;
        assert!(
            (moved[0] - spot[0]).hypot(moved[2] - spot[2]) > 0.05,
            "not respawned"
        );
        // The scripted controller drives to its targets and never stands still that long.
        let mut goto = GoToController::new(cfg.robot.action_limit);
        let mut successes = 0;
        for _ in 0..1500 {
            let info = env.step(goto.act(0, &env.observe()));
            match info.ending {
                Some(Ending::Success) => {
                    assert!(!info.placed, "a chained success drives on from where it is");
                    successes += 1;
                }
                Some(Ending::Stalled) => panic!("a driving robot stalled"),
                _ => {}
            }
        }
        assert!(successes >= 10, "{successes} successes");
    }

    /// The legs (start, target) an env drives in its first `legs` episodes under `act`.
    fn legs(cfg: &SimConfig, legs: u64, mut act: impl FnMut(&Env) -> [f32; 2]) -> Vec<[f64; 4]> {
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut env = Env::new(0, cfg, &terrain, 9);
        let mut seen = Vec::new();
        while env.episode_index < legs {
            if seen.len() as u64 == env.episode_index {
                let (s, t) = (env.episode.start, env.episode.target);
                seen.push([s[0], s[1], t[0], t[1]]);
            }
            env.step(act(&env));
        }
        seen
    }

    #[test]
    fn an_evaluation_course_gives_every_policy_the_same_legs() {
        let mut cfg = SimConfig::default();
        cfg.task.episodes = EpisodeStart::Course;
        // One policy reaches its targets, the other drives straight off and fails every leg.
        let mut goto = GoToController::new(cfg.robot.action_limit);
        let reaching = legs(&cfg, 4, |env| goto.act(0, &env.observe()));
        let limit = cfg.robot.action_limit as f32;
        let failing = legs(&cfg, 4, |_| [limit, limit]);
        assert_eq!(reaching.len(), 4);
        for (a, b) in reaching.iter().zip(&failing) {
            // Targets are the same draws; starts differ at most by the f32 placement.
            assert!(
                a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6),
                "{a:?} vs {b:?}"
            );
        }
        for w in reaching.windows(2) {
            let (end, start) = ([w[0][2], w[0][3]], [w[1][0], w[1][1]]);
            assert!((end[0] - start[0]).abs() < 1e-6 && (end[1] - start[1]).abs() < 1e-6);
        }
        // Every leg after the first places the robot anew, success or not.
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut env = Env::new(0, &cfg, &terrain, 9);
        let mut goto = GoToController::new(cfg.robot.action_limit);
        let ended: Vec<StepInfo> = std::iter::repeat_with(|| env.step(goto.act(0, &env.observe())))
            .take(2000)
            .filter(|i| i.ending.is_some())
            .take(3)
            .collect();
        assert_eq!(ended.len(), 3);
        assert!(ended.iter().all(|i| i.placed));
        // Chained episodes (SPEC S3) start where each robot stands instead.
        cfg.task.episodes = EpisodeStart::Chained;
        let mut goto = GoToController::new(cfg.robot.action_limit);
        let chained = legs(&cfg, 3, |env| goto.act(0, &env.observe()));
        assert_ne!(chained[1], legs(&cfg, 3, |_| [limit, limit])[1]);
    }

    #[test]
    fn both_terrain_colliders_and_the_imus_stepping_reach_the_world_and_drive_alike() {
        use rapier3d::prelude::ShapeType;
        let mut reached = Vec::new();
        for (collider, imu_stepping, kind) in [
            (TerrainCollider::Heightfield, false, ShapeType::HeightField),
            (TerrainCollider::Trimesh, false, ShapeType::TriMesh),
            (TerrainCollider::Heightfield, true, ShapeType::HeightField),
        ] {
            // 8 robots for 1,500 ticks: about 380 targets, so a count differs by a few
            // percent between steppings (the IMU's runs 2-5 % slower), not by the 10 % a
            // sample of 4 robots can stray.
            let mut cfg = SimConfig {
                envs: [(AreaKind::Flat, 0), (AreaKind::Rough, 8)].into(),
                threads: 1,
                ..SimConfig::default()
            };
            cfg.terrain.collider = collider;
            if imu_stepping {
                step_as_the_imu_needs(&mut cfg);
            }
            let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), collider);
            let mut fleet = crate::Fleet::new(&cfg, &terrain, 3);
            let env = &fleet.envs[0];
            let params = &env.world.integration_parameters;
            assert_eq!(
                (
                    params.num_solver_iterations,
                    params.num_internal_stabilization_iterations
                ),
                (
                    cfg.robot.solver_iterations,
                    cfg.robot.stabilization_iterations
                )
            );
            let ground = env
                .world
                .colliders
                .iter()
                .find(|(_, c)| c.parent().is_none());
            assert_eq!(ground.map(|(_, c)| c.shape().shape_type()), Some(kind));
            let mut goto = GoToController::new(cfg.robot.action_limit);
            let s = crate::standalone::drive(&mut fleet, &mut goto, 1500, |_, _| Ok(()))
                .expect("drive");
            assert_eq!(s.faults, 0);
            reached.push(s.episodes.successes as f64);
        }
        // The same ground under the same controller: about as many targets reached.
        assert!(reached[0] >= 200.0, "{reached:?}");
        for r in &reached[1..] {
            assert!((r / reached[0] - 1.0).abs() < 0.1, "{reached:?}");
        }
    }

    /// The stepping a simulated IMU needs (`IMU_MAX_PHYSICS_DT`): Unity's 0.02 s step, 5 per
    /// decision, 4 solver substeps each.
    fn step_as_the_imu_needs(cfg: &mut SimConfig) {
        (cfg.physics_dt, cfg.substeps, cfg.robot.solver_iterations) = (0.02, 5, 4);
    }

    /// Mean rolling standard deviation of `xs` over windows of `w`.
    fn rolling_std(xs: &[f64], w: usize) -> f64 {
        let stds: Vec<f64> = xs
            .windows(w)
            .map(|win| {
                let m = win.iter().sum::<f64>() / w as f64;
                (win.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (w - 1) as f64).sqrt()
            })
            .collect();
        stds.iter().sum::<f64>() / stds.len() as f64
    }

    #[test]
    fn the_imu_filter_tracks_the_true_pitch_and_its_rolling_std_per_area() {
        for (rough, most_pitch_deg) in [(false, 0.5), (true, 2.0)] {
            let mut cfg = SimConfig {
                envs: [
                    (AreaKind::Flat, usize::from(!rough)),
                    (AreaKind::Rough, usize::from(rough)),
                ]
                .into(),
                ..SimConfig::default()
            };
            cfg.observation = AttitudeSource::Imu;
            step_as_the_imu_needs(&mut cfg);
            let terrain =
                SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
            let mut env = Env::new(0, &cfg, &terrain, 11);
            let mut goto = GoToController::new(cfg.robot.action_limit);
            let (mut truth, mut seen) = (Vec::new(), Vec::new());
            for _ in 0..2000 {
                env.step(goto.act(0, &env.observe()));
                truth.push(env.pose().euler[0]);
                seen.push(env.observed_euler()[0]);
            }
            let sq: f64 = truth.iter().zip(&seen).map(|(t, s)| (s - t).powi(2)).sum();
            let rms = (sq / truth.len() as f64).sqrt().to_degrees();
            assert!(rms < 1.0, "rough {rough}: RMS pitch error {rms:.3}°");
            let most = truth.iter().fold(0.0f64, |m, t| m.max(t.abs()));
            assert!(
                most.to_degrees() > most_pitch_deg,
                "the ground pitched the robot"
            );
            // SPEC S7's signal, the rolling std of sin θx at window 70, as the IMU sees it.
            let sin = |xs: &[f64]| xs.iter().map(|x| x.sin()).collect::<Vec<_>>();
            let (t, s) = (rolling_std(&sin(&truth), 70), rolling_std(&sin(&seen), 70));
            assert!(
                (s / t - 1.0).abs() < 0.1,
                "rough {rough}: {s:.4} against {t:.4}"
            );
        }
    }

    #[test]
    fn an_imu_simulated_for_telemetry_only_changes_no_observation() {
        // The truth path is untouched: an IMU the observation does not read
        // (`sim.imu.simulate`, or `estimator.signal = "imu"`) leaves physics and
        // observations bit-identical, and only then are the filtered angles there.
        let mut cfg = SimConfig {
            envs: [(AreaKind::Flat, 0), (AreaKind::Rough, 1)].into(),
            ..SimConfig::default()
        };
        step_as_the_imu_needs(&mut cfg);
        let mut sensed = cfg.clone();
        sensed.imu.simulate = true;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut plain = Env::new(0, &cfg, &terrain, 11);
        let mut with_imu = Env::new(0, &sensed, &terrain, 11);
        let mut goto = GoToController::new(cfg.robot.action_limit);
        for _ in 0..300 {
            let obs = plain.observe();
            assert_eq!(obs, with_imu.observe());
            assert_eq!(plain.observed_euler(), plain.pose().euler);
            let action = goto.act(0, &obs);
            let (a, b) = (plain.step(action), with_imu.step(action));
            assert_eq!(a.reward.to_bits(), b.reward.to_bits());
        }
        assert_eq!(plain.imu_euler(), None);
        let imu = with_imu.imu_euler().expect("simulated");
        assert!((imu[0] - with_imu.pose().euler[0]).abs() < 2f64.to_radians());
    }

    #[test]
    fn a_mixed_course_env_reports_the_ground_under_it() {
        let cfg = SimConfig {
            envs: [(AreaKind::Flat, 0), (AreaKind::Mixed, 16)].into(),
            ..SimConfig::default()
        };
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let grounds: Vec<(AreaKind, AreaKind)> = (0..16)
            .map(|id| {
                let env = Env::new(id, &cfg, &terrain, 3);
                let [x, _, z] = env.pose().pos;
                assert!(cfg.terrain.mixed_area.contains(x, z, 0.0));
                let under = if cfg.terrain.mixed_parts[0].rect().contains(x, z, 0.0) {
                    AreaKind::Rough
                } else {
                    AreaKind::Flat
                };
                (env.ground(), under)
            })
            .collect();
        assert!(grounds.iter().all(|(g, under)| g == under), "{grounds:?}");
        for kind in [AreaKind::Flat, AreaKind::Rough] {
            assert!(grounds.iter().any(|(g, _)| *g == kind), "{grounds:?}");
        }
    }

    #[test]
    fn a_mixed_course_env_meets_the_friction_of_the_ground_under_it() {
        let mut cfg = SimConfig {
            envs: [(AreaKind::Flat, 0), (AreaKind::Mixed, 16)].into(),
            ..SimConfig::default()
        };
        cfg.terrain.mixed_parts[0].kind = AreaKind::Slope;
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut seen = Vec::new();
        for id in 0..16 {
            let mut env = Env::new(id, &cfg, &terrain, 3);
            env.step([0.0, 0.0]);
            let floor = env
                .world
                .colliders
                .iter()
                .find(|(_, c)| c.parent().is_none())
                .map(|(_, c)| (c.friction(), c.friction_combine_rule()))
                .expect("a floor");
            let want = match env.ground() {
                AreaKind::Slope => (0.5, CoefficientCombineRule::Min),
                _ => (1.0, CoefficientCombineRule::Average),
            };
            assert_eq!(floor, want, "env {id} on {:?}", env.ground());
            seen.push(env.ground());
        }
        assert!(seen.contains(&AreaKind::Slope) && seen.contains(&AreaKind::Flat));
    }
}
