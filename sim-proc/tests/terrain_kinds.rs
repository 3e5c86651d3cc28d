//! The terrain kinds beyond the paper's two against physical expectations: a robot slides
//! down a slope whose friction is below what its incline needs, gravel shakes the chassis at
//! higher frequencies than rough ground, and a wheel that spins fast digs into sand.

use common::config::{
    Area, AreaKind, RobotConfig, SimConfig, TerrainCollider, TerrainConfig, WheelModel,
};
use sim_proc::env::{SharedTerrain, build_world};
use sim_proc::terrain::Terrain;

/// A floor of `areas` alone: the mixed course every world has is a plain strip at
/// `mixed_area`, crossing no kind.
fn areas_only(areas: Vec<Area>, mixed_area: common::config::Rect) -> TerrainConfig {
    TerrainConfig {
        areas,
        mixed_area,
        mixed_parts: Vec::new(),
        ..TerrainConfig::default()
    }
}

/// A world with one slope area, x ∈ [0, 2], z ∈ [0, 2], of `incline_deg` and `friction`, its
/// floor colliding as `floor`, and robots built as `robot`.
fn slope(
    incline_deg: f64,
    friction: f64,
    floor: TerrainCollider,
    robot: RobotConfig,
) -> (SimConfig, SharedTerrain) {
    let slope_area = Area {
        kind: AreaKind::Slope,
        x: [0.0, 2.0],
        z: [0.0, 2.0],
    };
    let mixed = common::config::Rect {
        x: [0.0, 2.0],
        z: [2.5, 3.0],
    };
    let mut terrain = TerrainConfig {
        flat_relief: 0.0,
        ..areas_only(vec![slope_area], mixed)
    };
    terrain.slope.incline_deg = incline_deg;
    terrain.slope.friction = friction;
    terrain.collider = floor;
    let cfg = SimConfig {
        envs: [(AreaKind::Flat, 0), (AreaKind::Slope, 1)].into(),
        terrain,
        robot,
        ..SimConfig::default()
    };
    let shared = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    (cfg, shared)
}

/// The default robot with `wheels`.
fn wheeled(wheels: WheelModel) -> RobotConfig {
    RobotConfig {
        wheel_model: wheels,
        ..RobotConfig::default()
    }
}

/// How far (metres, along +X: uphill) a robot built as `robot`, dropped on the slope's western
/// face (colliding as `floor`) facing `yaw` and settled with its wheels held still, moves in
/// `seconds` with both wheels at `command`.
fn slope_travel(
    friction: f64,
    floor: TerrainCollider,
    robot: RobotConfig,
    yaw: f64,
    command: f32,
    seconds: f64,
) -> f64 {
    let (cfg, terrain) = slope(12.0, friction, floor, robot);
    let (mut world, robot) = build_world(&cfg, &terrain, [0.5, 1.0], yaw, AreaKind::Slope);
    let held = robot.command(&mut world, &cfg.robot, [0.0, 0.0]);
    // Let the drop settle before measuring.
    for _ in 0..25 {
        world.step_with_events(&held, &());
    }
    let x0 = world.bodies[robot.chassis].translation().x;
    let drive = robot.command(&mut world, &cfg.robot, [command; 2]);
    for _ in 0..(seconds / cfg.physics_dt).round() as usize {
        world.step_with_events(&drive, &());
    }
    f64::from(world.bodies[robot.chassis].translation().x - x0)
}

#[test]
fn a_robot_parked_across_a_slope_slides_at_low_friction_and_holds_at_one() {
    // Across the slope the wheels cannot roll downhill: only friction holds the robot. At 12°
    // it needs μ ≥ tan 12° ≈ 0.21 on every contact, and the skid has 0.05.
    for wheels in [WheelModel::Joint, WheelModel::Contact] {
        let floor = TerrainCollider::Heightfield;
        let slid = -slope_travel(0.3, floor, wheeled(wheels), 0.0, 0.0, 2.0);
        let held = -slope_travel(1.0, floor, wheeled(wheels), 0.0, 0.0, 2.0);
        assert!(
            slid > 0.2,
            "{wheels:?}: at μ = 0.3 it moved {slid} m downhill in 2 s"
        );
        assert!(
            held.abs() < 0.02,
            "{wheels:?}: at μ = 1 it moved {held} m in 2 s"
        );
    }
}

#[test]
fn a_robot_facing_up_a_slope_climbs_at_omega_r() {
    // Facing uphill (+X) on the 12° face at μ = 0.5: the climb needs about
    // m·g·sin 12°·r / 2 ≈ 0.013 N·m from each wheel, well inside the motors' 0.1 N·m, and
    // grip μ ≥ tan 12° ≈ 0.21, so the wheels should roll at the command from rest, on either
    // floor collider (a two-sided mesh held a jointed robot to 75 % of it).
    let r = SimConfig::default().robot.wheel_radius;
    let (seconds, incline) = (3.0, 12f64.to_radians());
    let uphill = std::f64::consts::FRAC_PI_2;
    for floor in [TerrainCollider::Heightfield, TerrainCollider::Trimesh] {
        for wheels in [WheelModel::Joint, WheelModel::Contact] {
            for command in [1.0f32, 3.0] {
                let climbed = slope_travel(0.5, floor, wheeled(wheels), uphill, command, seconds);
                let want = f64::from(command) * r * seconds * incline.cos();
                assert!(
                    (climbed - want).abs() < 0.1 * want,
                    "{floor:?}, {wheels:?} at {command} rad/s: climbed {climbed} m along X, \
                     ω·r·t·cos 12° = {want} m"
                );
            }
        }
    }
}

/// rapier's second stabilisation pass holds the wheel joints together at fewer substeps: at 4
/// substeps of one pass a jointed robot slides back down the 12° slope it should climb at
/// 1 rad/s, at 4 of two it climbs at the command, as at the default 6 of one (RESULTS R43, R47).
#[test]
fn four_substeps_climb_with_two_stabilisation_passes_and_slide_back_with_one() {
    let want = SimConfig::default().robot.wheel_radius * 3.0 * 12f64.to_radians().cos();
    let climb = |passes| {
        let robot = RobotConfig {
            wheel_model: WheelModel::Joint,
            solver_iterations: 4,
            stabilization_iterations: passes,
            ..RobotConfig::default()
        };
        let (floor, uphill) = (TerrainCollider::Heightfield, std::f64::consts::FRAC_PI_2);
        slope_travel(0.5, floor, robot, uphill, 1.0, 3.0)
    };
    let two = climb(2);
    assert!((two - want).abs() < 0.1 * want, "4 × 2: {two} m of {want}");
    let one = climb(1);
    assert!(one < 0.0, "4 × 1: {one} m, expected a slide back");
}

/// Four areas side by side and the go-to-target controller on each; a 1 cm grid resolves the
/// stones.
fn kinds_cfg(kind: AreaKind) -> SimConfig {
    let area = |kind, x0: f64| Area {
        kind,
        x: [x0, x0 + 1.5],
        z: [0.0, 3.0],
    };
    let mut cfg = SimConfig {
        terrain: TerrainConfig {
            cell_size: 0.01,
            ..areas_only(
                vec![
                    area(AreaKind::Flat, 0.0),
                    area(AreaKind::Rough, 2.5),
                    area(AreaKind::Gravel, 5.0),
                ],
                common::config::Rect {
                    x: [0.0, 6.5],
                    z: [3.5, 4.5],
                },
            )
        },
        ..SimConfig::default()
    };
    cfg.only_in(kind, 4);
    cfg
}

/// Over 4 envs driving to targets for 600 ticks (the first 100 dropped): the rolling std of
/// sin θx at window 70 (the paper's feature), and the RMS of its second difference
/// `s[t+1] − 2 s[t] + s[t−1]`, a high-pass that keeps what changes within a few ticks.
fn pitch_signal(cfg: &SimConfig) -> (f64, f64) {
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let mut fleet = sim_proc::Fleet::new(cfg, &terrain, 3);
    let mut ctrl = sim_proc::controllers::GoToController::new(cfg.robot.action_limit);
    let mut series = vec![Vec::new(); fleet.len()];
    sim_proc::standalone::drive(&mut fleet, &mut ctrl, 600, |row, _| {
        series[row.env as usize].push(row.sin_pitch);
        Ok(())
    })
    .expect("drive");
    let (mut std_sum, mut windows, mut curv_sq, mut curvs) = (0.0, 0, 0.0, 0);
    for s in &series {
        for w in s[100..].windows(70) {
            let m = w.iter().sum::<f64>() / 70.0;
            std_sum += (w.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 69.0).sqrt();
            windows += 1;
        }
        for c in s[100..].windows(3) {
            curv_sq += (c[2] - 2.0 * c[1] + c[0]).powi(2);
            curvs += 1;
        }
    }
    (
        std_sum / f64::from(windows),
        (curv_sq / f64::from(curvs)).sqrt(),
    )
}

#[test]
fn gravel_shakes_the_pitch_at_higher_frequencies_than_rough_ground() {
    let (flat_std, flat_hf) = pitch_signal(&kinds_cfg(AreaKind::Flat));
    let (rough_std, rough_hf) = pitch_signal(&kinds_cfg(AreaKind::Rough));
    let (gravel_std, gravel_hf) = pitch_signal(&kinds_cfg(AreaKind::Gravel));
    // Measured: high-pass 0.026 on gravel, 0.015 on rough, 0.004 on flat ground.
    assert!(
        gravel_hf - flat_hf > 1.3 * (rough_hf - flat_hf),
        "high-passed sin θx: gravel {gravel_hf}, rough {rough_hf}, flat {flat_hf}"
    );
    // The paper's feature sees gravel barely above flat ground and far below rough: it alone
    // cannot tell gravel (rolling std 0.039 against flat's 0.028 and rough's 0.096).
    assert!(
        gravel_std > flat_std && gravel_std < 0.6 * rough_std,
        "rolling std: gravel {gravel_std}, rough {rough_std}, flat {flat_std}"
    );
}

/// How far (metres, start to end) a robot dropped at a random pose on a 6 m square of `kind`
/// drives straight in 10 s with both wheels at `command`, and its wheels' sinkage then.
fn straight_run(kind: AreaKind, command: f32) -> (f64, [f64; 2]) {
    let mut cfg = SimConfig {
        terrain: TerrainConfig {
            cell_size: 0.02,
            ..areas_only(
                vec![Area {
                    kind,
                    x: [0.0, 6.0],
                    z: [0.0, 6.0],
                }],
                common::config::Rect {
                    x: [0.0, 6.0],
                    z: [7.0, 8.0],
                },
            )
        },
        ..SimConfig::default()
    };
    cfg.only_in(kind, 1);
    // Nothing ends the drive: no leaving the area, no target in reach.
    cfg.task.leave_margin = 10.0;
    cfg.task.delta = 1.0;
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let mut env = sim_proc::env::Env::new(0, &cfg, &terrain, 7);
    let start = env.pose().ground();
    for _ in 0..100 {
        let info = env.step([command; 2]);
        assert!(info.ending.is_none(), "{kind:?}: {info:?}");
    }
    let end = env.pose().ground();
    ((end[0] - start[0]).hypot(end[1] - start[1]), env.sinkage())
}

#[test]
fn a_robot_at_full_command_digs_into_sand_and_a_gentle_one_crosses_it() {
    let r = SimConfig::default().robot.wheel_radius;
    // Hard ground: full command (3 rad/s, 0.105 m/s at the rim) covers its ω·r·t.
    let (flat, flat_sink) = straight_run(AreaKind::Flat, 3.0);
    assert!(flat > 0.85 * 3.0 * r * 10.0, "flat: {flat} m");
    assert_eq!(flat_sink, [0.0; 2]);
    // Sand: the rim outruns the dig speed (0.06 m/s), the wheels sink within about a second
    // and then spin in their ruts.
    let (dug, dug_sink) = straight_run(AreaKind::Sand, 3.0);
    assert!(
        dug < 0.2 * flat,
        "sand at full command: {dug} m against {flat} m on flat"
    );
    assert!(dug_sink.iter().all(|s| *s > 0.99), "{dug_sink:?}");
    // Below the dig speed (1.5 rad/s, 0.0525 m/s) nothing sinks: the gentle robot goes farther.
    let (gentle, gentle_sink) = straight_run(AreaKind::Sand, 1.5);
    assert!(
        gentle > 0.85 * 1.5 * r * 10.0,
        "sand at 1.5 rad/s: {gentle} m"
    );
    assert_eq!(gentle_sink, [0.0; 2]);
}
