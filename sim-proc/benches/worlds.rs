//! One rapier world per robot (what the sim does) against K robots sharing one world, on flat
//! and rough ground: robot decision steps per second of one thread. Sharing a world lets
//! rapier pack the robots' joints and contacts into its 4-wide SIMD lanes and pay its
//! per-step overhead once, but makes a robot's bits depend on its world-mates and a respawn
//! disturb them. This measures what the sharing would buy (DESIGN §10).
//!
//! The robots stand on a grid in the area, each turning on its own circle (its own constant
//! wheel commands), so they spread over the ground and stay near it.

use common::config::{AreaKind, SimConfig};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rapier3d::prelude::PhysicsWorld;
use sim_proc::SharedTerrain;
use sim_proc::env::{build_world, drop_pose};
use sim_proc::robot::{self, Robot};
use sim_proc::terrain::Terrain;
use std::time::{Duration, Instant};

/// Where robot `i` of `k` starts in `area`: a grid of four columns over the area's middle.
fn spot(cfg: &SimConfig, area: AreaKind, i: usize, k: usize) -> [f64; 2] {
    let r = cfg
        .terrain
        .area(area)
        .expect("the default config has flat and rough areas");
    let rows = k.div_ceil(4).max(1);
    let (col, row) = ((i % 4) as f64, (i / 4) as f64);
    [
        r.x[0] + (r.x[1] - r.x[0]) * (col + 0.5) / 4.0,
        r.z[0] + (r.z[1] - r.z[0]) * (row + 0.5) / rows as f64,
    ]
}

/// Robot `i`'s wheel commands (rad/s): forward with a turn of its own.
fn command(i: usize) -> [f32; 2] {
    [2.0, 1.2 + 0.1 * (i % 8) as f32]
}

/// `k` robots, each in a world of its own.
fn separate(
    cfg: &SimConfig,
    terrain: &SharedTerrain,
    area: AreaKind,
    k: usize,
) -> Vec<(PhysicsWorld, Robot)> {
    (0..k)
        .map(|i| build_world(cfg, terrain, spot(cfg, area, i, k), 0.7 * i as f64, area))
        .collect()
}

/// `k` robots in one world (robots collide with the floor only, never with each other).
fn shared(
    cfg: &SimConfig,
    terrain: &SharedTerrain,
    area: AreaKind,
    k: usize,
) -> (PhysicsWorld, Vec<Robot>) {
    let (mut world, first) = build_world(cfg, terrain, spot(cfg, area, 0, k), 0.0, area);
    let mut robots = vec![first];
    for i in 1..k {
        let pose = drop_pose(cfg, terrain, spot(cfg, area, i, k), 0.7 * i as f64);
        robots.push(robot::build(&mut world, &cfg.robot, pose));
    }
    (world, robots)
}

/// One decision step of `world`'s robots: commands, then the physics substeps.
fn step(cfg: &SimConfig, world: &mut PhysicsWorld, robots: &[Robot], first: usize) {
    let mut drive = None;
    for (i, r) in robots.iter().enumerate() {
        drive = Some(r.command(world, &cfg.robot, command(first + i)));
    }
    // Jointed wheels (the default) carry no hook flag: the hook is never called.
    let drive = drive.expect("at least one robot");
    for _ in 0..cfg.substeps {
        world.step_with_events(&drive, &());
    }
}

fn robots_per_world(c: &mut Criterion) {
    let cfg = SimConfig::default();
    let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
    let mut group = c.benchmark_group("robots_per_world");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    for (area, name) in [(AreaKind::Flat, "flat"), (AreaKind::Rough, "rough")] {
        for k in [1usize, 4, 8] {
            group.throughput(Throughput::Elements(k as u64));
            let mut worlds = separate(&cfg, &terrain, area, k);
            group.bench_function(BenchmarkId::new(format!("{name}/separate"), k), |b| {
                b.iter_custom(|iters| {
                    let start = Instant::now();
                    for _ in 0..iters {
                        for (i, (world, robot)) in worlds.iter_mut().enumerate() {
                            step(&cfg, world, std::slice::from_ref(robot), i);
                        }
                    }
                    start.elapsed()
                });
            });
            let (mut world, robots) = shared(&cfg, &terrain, area, k);
            group.bench_function(BenchmarkId::new(format!("{name}/shared"), k), |b| {
                b.iter_custom(|iters| {
                    let start = Instant::now();
                    for _ in 0..iters {
                        step(&cfg, &mut world, &robots, 0);
                    }
                    start.elapsed()
                });
            });
        }
    }
    group.finish();
}

criterion_group!(benches, robots_per_world);
criterion_main!(benches);
