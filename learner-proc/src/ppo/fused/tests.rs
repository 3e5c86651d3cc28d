use super::*;
use crate::ppo::tests::{OwnedRollout, learner, small_config};
use common::OBS_DIM;
use common::config::PpoEngine;

/// The fused engine's minibatch gradient, shards added in order, against burn's autodiff of
/// the same loss on the same rows: with and without value clipping, and with a log-std and
/// weights far from their initial values so that no term vanishes.
#[test]
fn fused_gradients_match_burns_autodiff() {
    for (clip_vloss, shard_size) in [(false, 64), (true, 16), (false, 7)] {
        let mut cfg = small_config(64, 10);
        cfg.ppo.clip_vloss = clip_vloss;
        cfg.ppo.shard_size = shard_size;
        cfg.ppo.max_grad_norm = 1000.0; // burn's buffer then holds the unclipped gradient
        cfg.ppo.ent_coef = 0.01;
        let mut l = learner(&cfg, 21);
        let mut rng = Rng::new(22);
        for p in &mut l.params {
            *p += (0.05 * rng.normal()) as f32;
        }
        let rollout = OwnedRollout::acted_by(&l, 32, 4, 23);
        let (steps, envs) = super::super::batch::check_rollout(&rollout.view()).expect("rollout");
        assert_eq!(steps * envs, 128);
        let batch = l.batch(&rollout.view(), envs).expect("batch");
        let mb_inds: Vec<usize> = (0..64).map(|i| (i * 37) % 128).collect();

        let mut burn_grads = vec![0.0; l.params.len()];
        let burn = l
            .minibatch_step(
                &batch,
                &mb_inds,
                &mut l.params.clone(),
                &mut l.adam.clone(),
                &mut burn_grads,
                1e-3,
            )
            .expect("burn step");

        let shared = Shared::new(&l, &batch, 128, 1, 1e-3);
        let mut ws = Workspace::new(&shared, shard_size.min(64));
        shared.compute_items(0, &l.params, &mb_inds, &mut ws);
        let mut fused = vec![0.0f32; l.params.len()];
        let mut total = ShardSums::default();
        for net in Net::BOTH {
            let span = net.range(&l.shape);
            for item in &shared.items[net as usize] {
                let item = item.read().expect("item");
                fused[span.clone()]
                    .iter_mut()
                    .zip(&item.grads)
                    .for_each(|(a, g)| *a += g);
                total.add(&item.sums);
            }
        }
        let scale = burn_grads.iter().fold(0.0f32, |m, g| m.max(g.abs()));
        assert!(scale > 1e-3, "a vanishing gradient proves nothing");
        for (i, (f, b)) in fused.iter().zip(&burn_grads).enumerate() {
            assert!(
                (f - b).abs() <= 2e-4 * scale,
                "clip {clip_vloss}, shard {shard_size}: parameter {i}: fused {f} vs burn {b}"
            );
        }
        let stats = shared.stats(&total, 0.0);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * (1.0 + b.abs());
        assert!(close(stats.pg_loss, burn.pg_loss), "{stats:?} vs {burn:?}");
        assert!(close(stats.v_loss, burn.v_loss), "{stats:?} vs {burn:?}");
        assert!(close(stats.entropy, burn.entropy), "{stats:?} vs {burn:?}");
        assert!(
            close(stats.approx_kl, burn.approx_kl),
            "{stats:?} vs {burn:?}"
        );
        assert_eq!(stats.clipfrac, burn.clipfrac);
    }
}

/// Three updates on 1 to 4 threads give bit-identical weights, optimizer state and RNG: the
/// shards and parts, not the threads, fix the order of every sum.
#[test]
fn any_thread_count_gives_the_same_weights() {
    let run = |threads: usize, shard_size: usize| {
        let mut cfg = small_config(64, 10);
        cfg.ppo.threads = threads;
        cfg.ppo.shard_size = shard_size;
        let mut l = learner(&cfg, 31);
        assert_eq!(l.update_threads(), threads);
        // 384 rows: two chunks of the critic's value pass.
        let rollout = OwnedRollout::acted_by(&l, 96, 4, 32);
        for _ in 0..3 {
            l.update(&rollout.view()).expect("update");
        }
        (l.params, l.adam, l.rng)
    };
    let one = run(1, 16);
    assert_eq!(
        one.1.step,
        3 * 2 * 6,
        "3 updates × 2 epochs × 6 minibatches"
    );
    for threads in [2, 3, 4] {
        let other = run(threads, 16);
        assert!(
            one.0
                .iter()
                .zip(&other.0)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{threads} threads changed the weights"
        );
        assert_eq!((&one.1, &one.2), (&other.1, &other.2), "{threads} threads");
    }
    let wider = run(2, 32);
    assert_ne!(one.0, wider.0, "the shard size orders the sums");
}

/// A fused update trains on what the burn engine trains on: the same losses to rounding, and
/// the same direction of travel.
#[test]
fn fused_and_burn_updates_report_the_same_losses() {
    let update = |engine: PpoEngine| {
        let mut cfg = small_config(64, 10);
        cfg.ppo.engine = engine;
        cfg.ppo.epochs = 1;
        let mut l = learner(&cfg, 41);
        let before = l.params.clone();
        let rollout = OwnedRollout::acted_by(&l, 64, 4, 42);
        let m = l.update(&rollout.view()).expect("update");
        let step: Vec<f32> = l.params.iter().zip(&before).map(|(a, b)| a - b).collect();
        (m, step)
    };
    let (fused, f_step) = update(PpoEngine::Fused);
    let (burn, b_step) = update(PpoEngine::Burn);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * (1.0 + b.abs());
    assert!(
        close(fused.policy_loss, burn.policy_loss),
        "{fused:?}\n{burn:?}"
    );
    assert!(
        close(fused.value_loss, burn.value_loss),
        "{fused:?}\n{burn:?}"
    );
    assert!(
        close(fused.grad_norm, burn.grad_norm),
        "{fused:?}\n{burn:?}"
    );
    assert!(close(fused.entropy, burn.entropy), "{fused:?}\n{burn:?}");
    let dot: f64 = f_step
        .iter()
        .zip(&b_step)
        .map(|(a, b)| f64::from(a * b))
        .sum();
    let norm = |v: &[f32]| v.iter().map(|x| f64::from(x * x)).sum::<f64>().sqrt();
    let cosine = dot / (norm(&f_step) * norm(&b_step));
    assert!(cosine > 0.99, "cosine {cosine}");
}

/// A non-finite loss fails the update on every worker alike and leaves the learner as it was.
#[test]
fn a_non_finite_loss_fails_the_update_on_all_workers() {
    let mut cfg = small_config(64, 10);
    cfg.ppo.threads = 2;
    cfg.ppo.shard_size = 16;
    let mut l = learner(&cfg, 51);
    let rollout = OwnedRollout::acted_by(&l, 16, 4, 52);
    let critic_head = l.shape.blocks[l.shape.blocks.len() - 2];
    l.params[critic_head.offset] = f32::INFINITY;
    let before = (l.params.clone(), l.adam.clone(), l.counters);
    let e = l.update(&rollout.view()).expect_err("an infinite value");
    assert!(e.to_string().contains("loss or gradient"), "{e}");
    assert_eq!((l.params.clone(), l.adam.clone(), l.counters), before);
}

/// The critic's values of a rollout, in chunks over two threads, agree with burn's.
#[test]
fn fused_values_match_burns() {
    let mut cfg = small_config(64, 10);
    cfg.ppo.threads = 2;
    let mut l = learner(&cfg, 61);
    let mut rng = Rng::new(62);
    for p in &mut l.params {
        *p += (0.05 * rng.normal()) as f32;
    }
    let obs: Vec<[f32; OBS_DIM]> = (0..600)
        .map(|_| std::array::from_fn(|_| (2.0 * rng.normal()) as f32))
        .collect();
    let x = l.normalised(obs.iter().copied());
    let fused = l.values_fused(&x);
    let burn = l.values_normalised(x).expect("burn values");
    assert_eq!(fused.len(), 600);
    let scale = burn.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(scale > 0.1, "a flat critic proves nothing");
    for (i, (f, b)) in fused.iter().zip(&burn).enumerate() {
        assert!(
            (f - b).abs() <= 1e-5 * scale,
            "row {i}: fused {f} vs burn {b}"
        );
    }
}
