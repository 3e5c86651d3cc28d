//! Decision steps per second of the simulator on rough ground (the expensive case: most of a
//! physics step is heightfield contact), for 1, 8 and 64 envs with 1 and 2 threads. This is
//! the sim's share of the end-to-end throughput target (≥ 3,000 decision steps/s per core).

use common::config::SimConfig;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sim_proc::controllers::{Controller, GoToController};
use sim_proc::terrain::Terrain;
use sim_proc::{Batch, SharedTerrain, StepInfo};
use std::time::Duration;

fn decision_steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim_decision_step_rough");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1));
    for envs in [1usize, 8, 64] {
        for threads in [1usize, 2] {
            let cfg = SimConfig {
                flat_envs: 0,
                rough_envs: envs,
                threads,
                ..SimConfig::default()
            };
            let terrain = SharedTerrain::new(Terrain::procedural(&cfg.terrain));
            let mut batch = Batch::new(&cfg, &terrain, 1);
            let mut ctrl = GoToController::new(cfg.robot.action_limit);
            let mut obs = vec![[0.0f32; common::OBS_DIM]; envs];
            let mut actions = vec![[0.0f32; 2]; envs];
            let mut infos = vec![StepInfo::default(); envs];
            batch.observe(&mut obs);
            group.throughput(Throughput::Elements(envs as u64));
            group.bench_function(BenchmarkId::new(format!("{threads}_threads"), envs), |b| {
                b.iter(|| {
                    for (i, a) in actions.iter_mut().enumerate() {
                        *a = ctrl.act(i, &obs[i]);
                    }
                    batch.step(&actions, &mut infos, &mut obs);
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, decision_steps);
criterion_main!(benches);
