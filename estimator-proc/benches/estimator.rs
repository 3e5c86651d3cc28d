//! Benchmarks of the estimator's two hot paths.
//!
//! - `em_fit/N`: a full fit (default config: 2 components, 5 k-means++ restarts, tol 1e-8,
//!   ≤ 500 iterations) on N window-std-like values. This is what `analyze` pays per window and
//!   what an online refit pays on its pool (default 20 000 values), so it bounds how often the
//!   runtime can afford to refit.
//! - `online/observe`: one env's per-tick update with a fitted model and the HMM filter on
//!   (rolling std, posterior, forward step), refits pushed out of the measurement. The
//!   runtime pays this for every env on every 0.1 s tick; the target is < 1 µs.
//! - `online/observe_with_refits`: the same call with the default refit schedule (every 500
//!   ticks on a 20 000-value pool, 8 envs), i.e. the amortised cost including warm-started
//!   refits.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use estimator_proc::gmm::{self, FitOptions};
use estimator_proc::{Gmm, OnlineEstimator};
use std::hint::black_box;

/// Window-std-like values: 40 % flat (0.03 ± 0.01), 60 % rough (0.09 ± 0.03), as SPEC S7.
fn mixture_data(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = common::Rng::new(seed);
    (0..n)
        .map(|_| {
            if rng.uniform() < 0.4 {
                0.03 + 0.01 * rng.normal()
            } else {
                0.09 + 0.03 * rng.normal()
            }
        })
        .collect()
}

fn em_fit(c: &mut Criterion) {
    let opts = FitOptions::from_config(&common::config::EstimatorConfig::default(), 1);
    let mut group = c.benchmark_group("em_fit");
    group.sample_size(10);
    for n in [1_000, 10_000, 100_000] {
        let data = mixture_data(n, 7);
        group.bench_with_input(BenchmarkId::from_parameter(n), &data, |b, data| {
            b.iter(|| gmm::fit(black_box(data), &opts));
        });
    }
    group.finish();
}

/// Pitch samples for 8 envs: the first half flat (σ 0.02), the rest rough (σ 0.08).
fn pitch_stream(len: usize) -> Vec<f64> {
    let mut rng = common::Rng::new(3);
    (0..len)
        .map(|i| if i % 8 < 4 { 0.02 } else { 0.08 } * rng.normal())
        .collect()
}

fn online(c: &mut Criterion) {
    const ENVS: usize = 8;
    let stream = pitch_stream(1 << 16);
    let mut group = c.benchmark_group("online");
    let model = Gmm::new(vec![0.5, 0.5], vec![0.02, 0.08], vec![1e-4, 1e-3]).expect("model");
    let steady = common::config::EstimatorConfig {
        refit_every: 1_000_000,
        ..Default::default()
    };
    let mut est = OnlineEstimator::with_model(&steady, ENVS, 1, model).expect("estimator");
    let mut i = 0usize;
    group.bench_function("observe", |b| {
        b.iter(|| {
            i = (i + 1) & (stream.len() - 1);
            black_box(est.observe(i % ENVS, stream[i]))
        });
    });
    let mut est = OnlineEstimator::new(&common::config::EstimatorConfig::default(), ENVS, 1)
        .expect("estimator");
    let mut i = 0usize;
    group.bench_function("observe_with_refits", |b| {
        b.iter(|| {
            i = (i + 1) & (stream.len() - 1);
            black_box(est.observe(i % ENVS, stream[i]))
        });
    });
    group.finish();
}

criterion_group!(benches, em_fit, online);
criterion_main!(benches);
