//! Physics scene tests: the robot against physical expectations (SPEC S2), and the
//! simulator's determinism and fault handling.

use common::config::{AreaKind, SimConfig, TerrainConfig, WheelModel};
use sim_proc::controllers::{GoToController, RandomController};
use sim_proc::env::{SharedTerrain, build_world, unity_euler};
use sim_proc::standalone::drive;
use sim_proc::terrain::Terrain;
use sim_proc::{Env, Fleet};

/// Both ways a wheel can drive; every scene below holds for each.
const WHEELS: [WheelModel; 2] = [WheelModel::Joint, WheelModel::Contact];

/// A perfectly flat floor: no micro-relief, no bumps; robots with `wheels`.
fn plane(wheels: WheelModel) -> (SimConfig, SharedTerrain) {
    let mut cfg = SimConfig {
        terrain: TerrainConfig {
            flat_relief: 0.0,
            rough_amplitude: 0.0,
            ..TerrainConfig::default()
        },
        ..SimConfig::default()
    };
    cfg.robot.wheel_model = wheels;
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    (cfg, terrain)
}

/// Drives a robot placed at (-1, -0.25) facing +Z with constant wheel speeds and returns the
/// chassis pose after every physics step.
fn drive_const(
    wheels: WheelModel,
    speeds: [f32; 2],
    settle_s: f64,
    drive_s: f64,
) -> Vec<(glam::Vec3, glam::Quat)> {
    let (cfg, terrain) = plane(wheels);
    let (mut world, robot) = build_world(&cfg, &terrain, [-1.0, -0.25], 0.0, AreaKind::Flat);
    let steps = |s: f64| (s / cfg.physics_dt).round() as usize;
    let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
    for _ in 0..steps(settle_s) {
        world.step_with_events(&held, &());
    }
    let drive = robot.command(&mut world, &cfg.robot, speeds);
    let mut poses = Vec::new();
    for _ in 0..steps(drive_s) {
        world.step_with_events(&drive, &());
        let b = &world.bodies[robot.chassis];
        poses.push((b.translation(), *b.rotation()));
    }
    poses
}

#[test]
fn rests_at_the_geometric_height_on_flat_ground() {
    for wheels in WHEELS {
        let poses = drive_const(wheels, [0.0, 0.0], 2.0, 0.5);
        let (p, q) = poses[poses.len() - 1];
        // The axle (the chassis origin) rests one wheel radius above the plane.
        let want = SimConfig::default().robot.wheel_radius as f32;
        assert!(
            (p.y - want).abs() < 0.002,
            "{wheels:?}: axle at {} m, expected {want} m",
            p.y
        );
        // Level: the skid's bottom is level with the wheels'.
        let [pitch, _, roll] = unity_euler(q);
        assert!(
            pitch.abs() < 0.01 && roll.abs() < 0.01,
            "{wheels:?}: pitch {pitch} roll {roll}"
        );
    }
}

#[test]
fn a_dropped_robot_falls_as_half_g_t_squared_on_the_moon_and_on_earth() {
    for g in [1.62, 9.81] {
        let (mut cfg, terrain) = plane(WheelModel::Joint);
        cfg.gravity = g;
        cfg.physics_dt = 1.0 / 240.0;
        let (mut world, robot) = build_world(&cfg, &terrain, [-1.0, -0.25], 0.0, AreaKind::Flat);
        // Lifted 2 m, still: 0.4 s of free fall drops it at most 0.8 m.
        for (_, body) in world.bodies.iter_mut() {
            body.set_translation(body.translation() + glam::Vec3::Y * 2.0, true);
            body.set_linvel(glam::Vec3::ZERO, true);
            body.set_angvel(glam::Vec3::ZERO, true);
        }
        let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
        let start = world.bodies[robot.chassis].translation().y;
        let n: u32 = 96;
        for _ in 0..n {
            world.step_with_events(&held, &());
        }
        let drop = f64::from(start - world.bodies[robot.chassis].translation().y);
        let t = f64::from(n) * cfg.physics_dt;
        let want = 0.5 * g * t * t;
        // The integrator's steps land (1 + 1/n) past the continuous curve: 1 % here.
        assert!(
            (drop / want - 1.0).abs() < 0.015,
            "g = {g}: fell {drop:.4} m in {t} s, ½·g·t² = {want:.4} m"
        );
    }
}

/// The forward acceleration (m/s²) of a robot on a plane whose wheel motors push at their
/// torque limit `torque` (commanded far beyond what they reach), with the chassis refitted to
/// `chassis_mass` and a `payload` on top, as a world drawn by `sim.randomize` refits it. The
/// skid is frictionless, so the wheels' push is the only horizontal force.
fn torque_limited_acceleration(torque: f64, chassis_mass: f64, payload: f64) -> f64 {
    let (mut cfg, terrain) = plane(WheelModel::Joint);
    cfg.physics_dt = 1.0 / 120.0;
    cfg.robot.caster_friction = 0.0;
    cfg.robot.motor_max_torque = torque;
    let (mut world, robot) = build_world(&cfg, &terrain, [-1.0, -0.25], 0.0, AreaKind::Flat);
    cfg.robot.chassis_mass = chassis_mass;
    robot.refit(&mut world, &cfg.robot, [0.0; 3], payload);
    let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
    for _ in 0..120 {
        world.step_with_events(&held, &());
    }
    let drive = robot.command(&mut world, &cfg.robot, [100.0, 100.0]);
    let mut v = Vec::new();
    for _ in 0..48 {
        world.step_with_events(&drive, &());
        v.push(f64::from(world.bodies[robot.chassis].linvel().z));
    }
    // From 0.1 s to 0.4 s after the command: past the first contact transients.
    (v[47] - v[11]) / (36.0 * cfg.physics_dt)
}

#[test]
fn a_heavier_robot_accelerates_less_under_the_same_torque_as_f_equals_m_a() {
    let r = SimConfig::default().robot;
    let torque = 0.005;
    // Two wheels push 2τ/r; the wheels' own rolling (a solid ball's I = 2/5·m·r²) adds
    // I/r² each to the mass the push accelerates.
    let force = 2.0 * torque / r.wheel_radius;
    let wheels = 2.0 * (r.wheel_mass + 0.4 * r.wheel_mass);
    for (chassis, payload) in [(0.3, 0.0), (0.6, 0.0), (0.3, 0.3)] {
        let a = torque_limited_acceleration(torque, chassis, payload);
        let want = force / (chassis + payload + wheels);
        assert!(
            (a / want - 1.0).abs() < 0.1,
            "chassis {chassis} kg + payload {payload} kg: {a:.3} m/s², F/m = {want:.3} m/s²"
        );
    }
    let light = torque_limited_acceleration(torque, 0.3, 0.0);
    let heavy = torque_limited_acceleration(torque, 0.6, 0.0);
    assert!(
        heavy < 0.6 * light,
        "twice the chassis: {heavy:.3} against {light:.3} m/s²"
    );
}

#[test]
fn a_push_of_impulse_j_changes_the_robots_velocity_by_j_over_m() {
    let (mut cfg, terrain) = plane(WheelModel::Joint);
    cfg.physics_dt = 1.0 / 240.0;
    let (mut world, robot) = build_world(&cfg, &terrain, [-1.0, -0.25], 0.0, AreaKind::Flat);
    for (_, body) in world.bodies.iter_mut() {
        body.set_translation(body.translation() + glam::Vec3::Y * 2.0, true);
        body.set_linvel(glam::Vec3::ZERO, true);
    }
    let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
    let r = &cfg.robot;
    let total = r.chassis_mass + 2.0 * r.wheel_mass;
    let j = glam::Vec3::new(0.12, 0.0, -0.05);
    world.bodies[robot.chassis].apply_impulse(j, true);
    let chassis_now = world.bodies[robot.chassis].linvel();
    assert!((chassis_now - j / r.chassis_mass as f32).length() < 1e-5);
    // Through the joints the whole robot takes it: its centre of mass moves at J/M, in the
    // air (gravity pulls along y only).
    for _ in 0..24 {
        world.step_with_events(&held, &());
    }
    let momentum: glam::Vec3 = world
        .bodies
        .iter()
        .map(|(_, b)| b.linvel() * b.mass())
        .sum();
    let v = glam::Vec3::new(momentum.x, 0.0, momentum.z) / total as f32;
    let want = j / total as f32;
    assert!(
        (v - want).length() < 1e-3 * want.length(),
        "{v} against J/M = {want}"
    );
}

/// Where the robot of an env standing on a plane is after each decision step: pushed every
/// second by `[sim.randomize]` when `pushed`.
fn positions_at_rest(pushed: bool) -> Vec<[f64; 3]> {
    let (mut cfg, terrain) = plane(WheelModel::Joint);
    if pushed {
        cfg.randomize.push_impulse = [0.3, 0.3];
        cfg.randomize.push_interval = 1.0;
    }
    let mut env = Env::new(0, &cfg, &terrain, 5);
    (0..25)
        .map(|_| {
            env.step([0.0, 0.0]);
            env.pose().pos
        })
        .collect()
}

#[test]
fn a_randomized_world_pushes_the_robot_every_push_interval() {
    let (still, pushed) = (positions_at_rest(false), positions_at_rest(true));
    let moved = |a: [f64; 3], b: [f64; 3]| (a[0] - b[0]).hypot(a[2] - b[2]);
    // 1 s at 0.1 s per decision step: the push comes at the episode's step 10, the 11th.
    // Before it the two differ only by the refitted chassis's rounding.
    for (a, b) in still[..10].iter().zip(&pushed[..10]) {
        assert!(
            moved(*a, *b) < 1e-5,
            "no push before the first second: {a:?} {b:?}"
        );
    }
    // After it the pushed robot is elsewhere: 0.3 N·s on 0.36 kg is 0.8 m/s, braked by the
    // held wheels within a few centimetres.
    let apart = moved(pushed[24], still[24]);
    assert!(
        apart > 0.01,
        "pushed robot {apart:.4} m from the unpushed one"
    );
}

/// How far a robot with its wheels held slides in 3 s down a plane tilted by `incline_deg`
/// (gravity turned instead of the ground), in `configs/moon.toml`'s world: lunar gravity and
/// regolith under the wheels, and here under the skid too (its own friction no lower than the
/// ground's), so that the whole robot stands on regolith as a block would.
fn moon_slide(incline_deg: f64) -> f64 {
    let moon = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/moon.toml");
    let mut cfg = common::Config::load(std::path::Path::new(moon))
        .expect("configs/moon.toml")
        .sim;
    cfg.terrain.flat_relief = 0.0;
    cfg.robot.caster_friction = 1.0;
    cfg.physics_dt = 1.0 / 120.0;
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let (mut world, robot) = build_world(&cfg, &terrain, [-1.0, -0.25], 0.0, AreaKind::Flat);
    let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
    for _ in 0..120 {
        world.step_with_events(&held, &());
    }
    let tilt = incline_deg.to_radians();
    let g = cfg.gravity as f32;
    world.gravity = glam::Vec3::new(0.0, -g * tilt.cos() as f32, -g * tilt.sin() as f32);
    let start = world.bodies[robot.chassis].translation();
    for _ in 0..360 {
        world.step_with_events(&held, &());
    }
    f64::from((world.bodies[robot.chassis].translation() - start).length())
}

#[test]
fn on_regolith_a_robot_holds_below_its_friction_angle_and_slides_above_it() {
    // configs/moon.toml: μ = 0.84 = tan 40°.
    let phi = 0.84f64.atan().to_degrees();
    let (below, above) = (moon_slide(phi - 5.0), moon_slide(phi + 5.0));
    assert!(below < 0.005, "{:.1}°: slid {below:.4} m", phi - 5.0);
    // A block sliding from rest at g·(sin θ − μ·cos θ) = 0.18 m/s² covers 0.82 m in 3 s.
    let theta = (phi + 5.0).to_radians();
    let want = 0.5 * 1.62 * (theta.sin() - 0.84 * theta.cos()) * 9.0;
    assert!(
        (above / want - 1.0).abs() < 0.15,
        "{:.1}°: slid {above:.3} m, a block {want:.3} m",
        phi + 5.0
    );
}

/// How far the robot of an env on a plane drives in each decision step of one physics step:
/// 5 s at rest, then both wheels commanded at 2 rad/s, with `latency` steps of delay.
fn steps_with_latency(latency: usize) -> Vec<f64> {
    let (mut cfg, terrain) = plane(WheelModel::Joint);
    cfg.substeps = 1;
    cfg.robot.command_latency = latency;
    let mut env = Env::new(0, &cfg, &terrain, 5);
    for _ in 0..150 {
        env.step([0.0, 0.0]);
    }
    let mut last = env.pose().pos;
    (0..40)
        .map(|_| {
            env.step([2.0, 2.0]);
            let p = env.pose().pos;
            let step = (p[0] - last[0]).hypot(p[2] - last[2]);
            last = p;
            step
        })
        .collect()
}

#[test]
fn a_latency_of_k_physics_steps_delays_the_response_by_k_steps() {
    // At rest the robot creeps about 0.06 mm a step; driving, it moves 0.8 mm in the first.
    let at_once = steps_with_latency(0);
    assert!(
        at_once[0] > 5e-4,
        "the undelayed robot moves at once: {at_once:?}"
    );
    for k in [1, 3] {
        let late = steps_with_latency(k);
        assert!(
            late[..k].iter().all(|d| *d < 1e-4),
            "k = {k}: at rest for k steps: {late:?}"
        );
        for (i, d) in at_once[..40 - k].iter().enumerate() {
            assert!(
                (late[i + k] - d).abs() < 2e-5,
                "k = {k}, step {i}: {} against {d}",
                late[i + k]
            );
        }
    }
}

#[test]
fn equal_commands_drive_straight_at_omega_r() {
    let omega = 3.0f32;
    let t = 5.0;
    let r = SimConfig::default().robot.wheel_radius as f32;
    let expected = omega * r * t as f32;
    for wheels in WHEELS {
        let poses = drive_const(wheels, [omega, omega], 1.0, t);
        let (start, end) = (poses[0].0, poses[poses.len() - 1].0);
        let along = end.z - start.z;
        assert!(
            (along - expected).abs() < 0.05 * expected,
            "{wheels:?}: travelled {along} m, ω·r·t = {expected} m"
        );
        assert!(
            (end.x - start.x).abs() < 0.02,
            "{wheels:?}: lateral drift {} m",
            end.x - start.x
        );
    }
}

/// The mean yaw rate (rad/s) over the poses after the first `skip_s` seconds.
fn yaw_rate(poses: &[(glam::Vec3, glam::Quat)], skip_s: f64) -> f64 {
    let dt = SimConfig::default().physics_dt;
    let yaws: Vec<f64> = poses.iter().map(|(_, q)| unity_euler(*q)[1]).collect();
    let from = (skip_s / dt) as usize;
    let mut turned = 0.0;
    for w in yaws[from..].windows(2) {
        let mut d = w[1] - w[0];
        if d > std::f64::consts::PI {
            d -= std::f64::consts::TAU;
        } else if d < -std::f64::consts::PI {
            d += std::f64::consts::TAU;
        }
        turned += d;
    }
    turned / ((yaws.len() - 1 - from) as f64 * dt)
}

#[test]
fn opposite_commands_turn_at_the_kinematic_yaw_rate() {
    let omega = 2.0f32;
    let cfg = SimConfig::default().robot;
    // Right wheel forward, left backward: yaw rate 2·ω·r / track, counter-clockwise about +Y.
    let expected = 2.0 * f64::from(omega) * cfg.wheel_radius / cfg.track_width;
    for wheels in WHEELS {
        // Skip 1 s of spin-up.
        let rate = yaw_rate(&drive_const(wheels, [-omega, omega], 1.0, 3.0), 1.0);
        assert!(
            (rate - expected).abs() < 0.1 * expected,
            "{wheels:?}: yaw rate {rate} rad/s, kinematic {expected} rad/s"
        );
    }
}

fn rough_cfg(envs: usize) -> SimConfig {
    SimConfig {
        envs: [(AreaKind::Flat, 0), (AreaKind::Rough, envs)].into(),
        ..SimConfig::default()
    }
}

#[test]
fn random_driving_on_rough_ground_stays_physical() {
    let cfg = rough_cfg(1);
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let mut env = Env::new(0, &cfg, &terrain, 11);
    let mut ctrl = RandomController::new(cfg.robot.action_limit, 10, 11);
    use sim_proc::controllers::Controller;
    let mut deepest = 0.0f64;
    for _ in 0..3000 {
        let a = ctrl.act(0, &env.observe());
        let info = env.step(a);
        assert_eq!(info.faults, 0, "non-finite state at tick {}", env.tick);
        let p = env.pose();
        assert!(p.is_finite());
        let tip = 60f64.to_radians();
        assert!(
            p.euler[0].abs() < tip && p.euler[2].abs() < tip,
            "flipped at tick {}: {:?}",
            env.tick,
            p.euler
        );
        for c in env.wheel_centres() {
            let depth = cfg.robot.wheel_radius - (c[1] - terrain.terrain.height_at(c[0], c[2]));
            deepest = deepest.max(depth);
        }
    }
    assert!(deepest < 0.005, "a wheel sank {deepest} m into the ground");
}

/// Mean over envs and ticks of the rolling std (window 70) of sin θx under go-to-target.
fn mean_rolling_std(cfg: &SimConfig, ticks: u64) -> f64 {
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let mut fleet = Fleet::new(cfg, &terrain, 3);
    let mut ctrl = GoToController::new(cfg.robot.action_limit);
    let mut series = vec![Vec::new(); fleet.len()];
    drive(&mut fleet, &mut ctrl, ticks, |row, _| {
        series[row.env as usize].push(row.sin_pitch);
        Ok(())
    })
    .expect("drive");
    let (mut sum, mut n) = (0.0, 0);
    for s in &series {
        for w in s[100..].windows(70) {
            let m = w.iter().sum::<f64>() / 70.0;
            sum += (w.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 69.0).sqrt();
            n += 1;
        }
    }
    sum / f64::from(n)
}

#[test]
fn pitch_varies_more_on_rough_than_flat_ground() {
    // SPEC S7's protocol: 500 ticks per env, the first 100 dropped, window 70.
    let flat = mean_rolling_std(
        &SimConfig {
            envs: [(AreaKind::Flat, 4), (AreaKind::Rough, 0)].into(),
            ..SimConfig::default()
        },
        500,
    );
    let rough = mean_rolling_std(&rough_cfg(4), 500);
    assert!(
        rough >= 3.0 * flat,
        "rolling std of sin θx: rough {rough}, flat {flat}"
    );
}

#[test]
fn same_seed_gives_identical_telemetry_whatever_the_thread_count() {
    let record = |threads: usize| {
        let cfg = SimConfig {
            envs: [(AreaKind::Flat, 2), (AreaKind::Rough, 2)].into(),
            threads,
            ..SimConfig::default()
        };
        let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
        let mut fleet = Fleet::new(&cfg, &terrain, 5);
        let mut ctrl = RandomController::new(3.0, 7, 5);
        let mut rows = Vec::new();
        drive(&mut fleet, &mut ctrl, 200, |r, _| {
            rows.push(format!("{r:?}"));
            Ok(())
        })
        .expect("drive");
        rows
    };
    let a = record(1);
    assert_eq!(a.len(), 800);
    assert_eq!(a, record(1), "same seed, same thread count");
    assert_eq!(a, record(2), "same seed, two threads");
}
