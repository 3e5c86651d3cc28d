//! PPO update throughput: minibatch samples × epochs per second of `Learner::update`, on a
//! 2048-transition rollout (8 envs × 256 steps, obs 10, act 2, 10 epochs), for the paper's
//! 128-128 network and for CleanRL's 64-64 (the PyTorch reference measured here, one thread:
//! 38k / 119k / 194k samples/s at minibatch 64 / 256 / 512), on burn's autodiff and on the
//! fused engine with 1 and 2 worker threads. The update is the learner's hot path; this is
//! what decides whether the simulator waits on it in sync mode.
//!
//! Time is wall time, since the fused engine's workers are several threads: run it on an
//! otherwise idle machine (a concurrent build on the same cores measures the build).

use std::hint::black_box;
use std::time::Duration;

use common::config::{Config, PpoEngine};
use common::policy::PolicyLayout;
use common::{OBS_DIM, Rng, Transition};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use learner_proc::{Learner, Rollout};

const ENVS: usize = 8;
const STEPS: usize = 256;
const EPOCHS: usize = 10;

fn config(hidden: &[usize], minibatch: usize, engine: PpoEngine, threads: usize) -> Config {
    let mut cfg = Config::default();
    cfg.ppo.engine = engine;
    cfg.ppo.threads = threads;
    cfg.ppo.hidden = hidden.to_vec();
    cfg.ppo.minibatch_size = minibatch;
    cfg.ppo.epochs = EPOCHS;
    // The same rollout is replayed every iteration: keep the learning rate from decaying and
    // the replayed transitions from counting as stale.
    cfg.run.total_steps = u64::MAX / 2;
    cfg.ppo.max_policy_lag = u32::MAX;
    cfg
}

/// A rollout whose actions and log-probabilities come from `learner`'s own policy, so ratios
/// and clipping behave as in training.
fn rollout(learner: &Learner, rng: &mut Rng) -> (Vec<Transition>, Vec<[f32; OBS_DIM]>) {
    let obs: Vec<[f32; OBS_DIM]> = (0..ENVS * STEPS)
        .map(|_| std::array::from_fn(|_| rng.normal() as f32))
        .collect();
    let sampled = learner.sample_actions(&obs, rng).expect("sample");
    let transitions = obs
        .iter()
        .zip(sampled)
        .enumerate()
        .map(|(i, (o, s))| Transition {
            obs: *o,
            action: s.action,
            logprob: s.logprob,
            reward: rng.normal() as f32,
            env: (i % ENVS) as u32,
            terminated: u8::from(rng.uniform() < 0.01),
            ..Transition::default()
        })
        .collect();
    let bootstrap = obs[..ENVS].to_vec();
    (transitions, bootstrap)
}

fn ppo_update(c: &mut Criterion) {
    // As the learner process does at start-up (`learner_proc::cli::main`).
    learner_proc::tune_allocator();
    let mut group = c.benchmark_group("ppo_update");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10))
        .warm_up_time(Duration::from_secs(2));
    group.throughput(Throughput::Elements((ENVS * STEPS * EPOCHS) as u64));
    let engines = [
        ("burn", PpoEngine::Burn, 1),
        ("fused-1t", PpoEngine::Fused, 1),
        ("fused-2t", PpoEngine::Fused, 2),
    ];
    for hidden in [[128, 128], [64, 64]] {
        for minibatch in [64, 256, 512] {
            for (name, engine, threads) in engines {
                let cfg = config(&hidden, minibatch, engine, threads);
                let layout = PolicyLayout::new(OBS_DIM, &hidden, 2);
                let mut learner = Learner::new(&cfg, layout, 1).expect("learner");
                let (transitions, bootstrap) = rollout(&learner, &mut Rng::new(2));
                let batch = Rollout {
                    transitions: &transitions,
                    bootstrap_obs: &bootstrap,
                    episodes: &[],
                };
                let id = BenchmarkId::new(
                    format!("{name}/{}-{}", hidden[0], hidden[1]),
                    format!("mb{minibatch}"),
                );
                group.bench_function(id, |b| {
                    b.iter(|| black_box(learner.update(&batch).expect("update")));
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, ppo_update);
criterion_main!(benches);
