//! Decision steps per second of the simulator on rough ground (the expensive case: most of a
//! physics step is heightfield contact), for 1, 8 and 64 envs with 1 and 2 threads. This is
//! the sim's share of the end-to-end throughput target (≥ 3,000 decision steps/s per core).
//!
//! Criterion reports wall-clock throughput per configuration. The closing table adds the same
//! runs per CPU-second of the whole process (all threads), the per-core figure the target
//! speaks of, which holds still while other work on this shared machine takes cores away from
//! the wall clock; "cores busy" (CPU time over wall time) shows how well the threads scale.
//! One env runs on one thread whatever the setting.

use common::config::{AreaKind, SimConfig};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sim_proc::controllers::{Controller, GoToController};
use sim_proc::terrain::Terrain;
use sim_proc::{Fleet, SharedTerrain, StepInfo};
use std::io::Write;
use std::time::{Duration, Instant};

/// Everything criterion timed for one configuration, warm-up included.
struct Row {
    envs: usize,
    threads: usize,
    steps: u64,
    wall: Duration,
    cpu: Duration,
}

fn decision_steps(c: &mut Criterion) {
    let mut rows = Vec::new();
    let mut group = c.benchmark_group("sim_decision_step_rough");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1));
    for envs in [1usize, 8, 64] {
        for threads in [1usize, 2] {
            let cfg = SimConfig {
                envs: [(AreaKind::Flat, 0), (AreaKind::Rough, envs)].into(),
                threads,
                ..SimConfig::default()
            };
            let terrain =
                SharedTerrain::new(Terrain::procedural(&cfg.terrain), cfg.terrain.collider);
            let mut fleet = Fleet::new(&cfg, &terrain, 1);
            let mut ctrl = GoToController::new(cfg.robot.action_limit);
            let mut obs = vec![[0.0f32; common::OBS_DIM]; envs];
            let mut actions = vec![[0.0f32; 2]; envs];
            let mut infos = vec![StepInfo::default(); envs];
            fleet.observe(&mut obs);
            let mut row = Row {
                envs,
                threads,
                steps: 0,
                wall: Duration::ZERO,
                cpu: Duration::ZERO,
            };
            group.throughput(Throughput::Elements(envs as u64));
            group.bench_function(BenchmarkId::new(format!("{threads}_threads"), envs), |b| {
                b.iter_custom(|iters| {
                    let (wall, cpu) = (Instant::now(), common::clock::process_cpu());
                    for _ in 0..iters {
                        for (i, a) in actions.iter_mut().enumerate() {
                            *a = ctrl.act(i, &obs[i]);
                        }
                        fleet.step(&actions, &mut infos, &mut obs);
                    }
                    let elapsed = wall.elapsed();
                    row.steps += iters * envs as u64;
                    row.wall += elapsed;
                    row.cpu += common::clock::process_cpu().saturating_sub(cpu);
                    elapsed
                });
            });
            rows.push(row);
        }
    }
    group.finish();
    print_table(&rows).expect("writing the summary table to stdout");
}

fn print_table(rows: &[Row]) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "\ndecision steps/s on rough ground (target ≥ 3,000 per core)"
    )?;
    writeln!(
        out,
        "| envs | threads | steps/s (wall clock) | steps/s per CPU-second | cores busy |"
    )?;
    writeln!(out, "|---:|---:|---:|---:|---:|")?;
    for r in rows {
        let (wall, cpu) = (r.wall.as_secs_f64(), r.cpu.as_secs_f64());
        writeln!(
            out,
            "| {} | {} | {:.0} | {:.0} | {:.2} |",
            r.envs,
            r.threads,
            r.steps as f64 / wall,
            r.steps as f64 / cpu,
            cpu / wall
        )?;
    }
    Ok(())
}

criterion_group!(benches, decision_steps);
criterion_main!(benches);
