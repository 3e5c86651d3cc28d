use super::minibatch::{kl_and_clipfrac, normalise_advantages};
use super::update::explained_variance;
use super::*;
use common::Policy;
use common::policy::Scratch;

/// A small config: 64-64 networks, `steps × envs` rollouts, LR decay over `updates` of them.
pub(crate) fn small_config(minibatch: usize, updates: u64) -> Config {
    let mut cfg = Config::default();
    cfg.ppo.hidden = vec![64, 64];
    cfg.ppo.minibatch_size = minibatch;
    cfg.ppo.epochs = 2;
    cfg.run.total_steps = updates * 64 * 4;
    cfg
}

pub(crate) fn learner(cfg: &Config, seed: u64) -> Learner {
    Learner::new(
        cfg,
        PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM),
        seed,
    )
    .expect("learner")
}

/// An owned rollout of `steps × envs` transitions acted by `learner`'s current policy, with
/// random rewards and some terminations and truncations.
pub(crate) struct OwnedRollout {
    pub transitions: Vec<Transition>,
    pub bootstrap: Vec<[f32; OBS_DIM]>,
}

impl OwnedRollout {
    pub(crate) fn acted_by(learner: &Learner, steps: usize, envs: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let mut obs = || -> [f32; OBS_DIM] {
            std::array::from_fn(|k| (k as f64 + 2.0 * rng.normal()) as f32)
        };
        let all: Vec<[f32; OBS_DIM]> = (0..steps * envs).map(|_| obs()).collect();
        let bootstrap = (0..envs).map(|_| obs()).collect();
        let finals: Vec<[f32; OBS_DIM]> = (0..steps * envs).map(|_| obs()).collect();
        let mut rng = Rng::new(seed + 1);
        let sampled = learner.sample_actions(&all, &mut rng).expect("sample");
        let transitions = all
            .iter()
            .zip(sampled)
            .enumerate()
            .map(|(i, (o, s))| Transition {
                obs: *o,
                action: s.action,
                final_obs: finals[i],
                logprob: s.logprob,
                reward: rng.normal() as f32,
                policy_version: learner.policy_version(),
                env: (i % envs) as u32,
                terminated: u8::from(rng.uniform() < 0.05),
                truncated: u8::from(rng.uniform() < 0.05),
                ..Transition::default()
            })
            .collect();
        Self {
            transitions,
            bootstrap,
        }
    }

    pub(crate) fn view(&self) -> Rollout<'_> {
        Rollout {
            transitions: &self.transitions,
            bootstrap_obs: &self.bootstrap,
            episodes: &[],
        }
    }
}

/// burn's actor forward on random weights, random normalisation statistics and inputs that
/// hit the observation clip agrees with `common::Policy` on the shipped flat vector.
#[test]
fn burn_actor_matches_common_policy() {
    let mut cfg = Config::default();
    cfg.ppo.obs_clip = 3.0;
    let mut learner = learner(&cfg, 1);
    let mut rng = Rng::new(2);
    for block in &learner.shape.blocks {
        let scale = 1.5 / (block.rows as f64).sqrt();
        learner.params[block.range()]
            .iter_mut()
            .for_each(|p| *p = (scale * rng.normal()) as f32);
    }
    learner
        .obs_norm
        .mean
        .iter_mut()
        .for_each(|m| *m = rng.normal());
    learner
        .obs_norm
        .var
        .iter_mut()
        .for_each(|v| *v = rng.range(0.01, 4.0));
    let obs: Vec<[f32; OBS_DIM]> = (0..64)
        .map(|_| std::array::from_fn(|_| (3.0 * rng.normal()) as f32))
        .collect();

    let burn_means = learner.mean_actions(&obs).expect("burn forward");
    let policy =
        Policy::new(learner.layout().clone(), learner.policy_weights(), 3.0).expect("layout");
    let mut scratch = Scratch::default();
    let mut worst = 0.0f32;
    for (o, b) in obs.iter().zip(&burn_means) {
        let mut m = [0.0; ACT_DIM];
        policy.mean_action(o, &mut m, &mut scratch);
        for k in 0..ACT_DIM {
            worst = worst.max((m[k] - b[k]).abs());
        }
    }
    assert!(worst < 1e-5, "max difference {worst}");
    assert!(
        burn_means.iter().any(|m| m[0].abs() > 0.1),
        "a trivial network proves nothing"
    );
    assert_eq!(
        policy.log_std(),
        &learner.params[learner.shape.blocks[learner.shape.log_std_block()].range()]
    );
}

/// The flat vector is obs mean, obs var, then the actor's blocks exactly as the learner holds them.
#[test]
fn policy_weights_round_trip_through_the_layout() {
    let mut learner = learner(&Config::default(), 3);
    learner.obs_norm.update(
        [[0.5f32; OBS_DIM], [1.5; OBS_DIM]]
            .iter()
            .map(<[f32; 10]>::as_slice),
    );
    let w = learner.policy_weights();
    let layout = learner.layout().clone();
    assert_eq!(w.len(), layout.len());
    let (mean, var) = learner.obs_norm.shipped();
    assert_eq!(&w[layout.obs_mean()..layout.obs_var()], mean.as_slice());
    assert_eq!(&w[layout.obs_var()..2 * OBS_DIM], var.as_slice());
    for (l, dense) in layout.dense_layers().iter().enumerate() {
        let (ws, bs) = (learner.shape.blocks[2 * l], learner.shape.blocks[2 * l + 1]);
        assert_eq!(&w[dense.weight..dense.bias], &learner.params[ws.range()]);
        assert_eq!(
            &w[dense.bias..dense.bias + dense.outputs],
            &learner.params[bs.range()]
        );
    }
    assert_eq!(
        &w[layout.log_std()..],
        &learner.params[learner.shape.blocks[learner.shape.log_std_block()].range()]
    );
}

/// Sampled log-probabilities agree with burn's: a one-minibatch, one-epoch update on the
/// policy's own actions starts (and, with one step, measures) at ratio 1.
#[test]
fn behaviour_logprobs_match_so_the_first_ratio_is_one() {
    let mut cfg = small_config(256, 10);
    cfg.ppo.epochs = 1;
    let mut learner = learner(&cfg, 4);
    let rollout = OwnedRollout::acted_by(&learner, 64, 4, 5);
    let m = learner.update(&rollout.view()).expect("update");
    assert!(
        m.approx_kl.abs() < 1e-6 && m.old_approx_kl.abs() < 1e-5,
        "{m:?}"
    );
    assert_eq!(m.clip_fraction, 0.0);
    assert_eq!(
        (m.update, m.global_step, m.policy_version, m.epochs),
        (1, 256, 1, 1)
    );
    assert!(m.value_loss > 0.0 && m.entropy > 2.0 && m.grad_norm > 0.0);
}

/// SPEC S6: 3e-4 decaying linearly to 0 over the run; constant when annealing is off.
/// Also: a checkpoint is due every `checkpoint-every` updates.
#[test]
fn learning_rate_decays_linearly_per_update() {
    let mut cfg = small_config(128, 4); // 4 updates of 256 transitions
    cfg.ppo.checkpoint_every = 2;
    let mut learner = learner(&cfg, 6);
    assert!(!learner.checkpoint_due());
    let rollout = OwnedRollout::acted_by(&learner, 64, 4, 7);
    let mut due = Vec::new();
    let mut lrs = Vec::new();
    for _ in 0..5 {
        lrs.push(
            learner
                .update(&rollout.view())
                .expect("update")
                .learning_rate,
        );
        due.push(learner.checkpoint_due());
    }
    assert_eq!(due, [false, true, false, true, false]);
    for (got, want) in lrs.iter().zip([3e-4, 2.25e-4, 1.5e-4, 0.75e-4, 0.0]) {
        assert!((got - want).abs() < 1e-9, "{lrs:?}");
    }
    cfg.ppo.anneal_lr = false;
    let mut flat = Learner::new(&cfg, learner.layout().clone(), 6).expect("learner");
    flat.update(&rollout.view()).expect("update");
    assert_eq!(flat.learning_rate(), 3e-4);
}

#[test]
fn malformed_rollouts_are_refused_without_side_effects() {
    let mut learner = learner(&small_config(64, 10), 8);
    let good = OwnedRollout::acted_by(&learner, 16, 4, 9);
    let before = learner.policy_weights();

    let short = Rollout {
        transitions: &good.transitions[..63],
        ..good.view()
    };
    let e = learner
        .update(&short)
        .expect_err("63 is not a multiple of 4");
    assert!(e.to_string().contains("63 transitions"), "{e}");

    let mut shuffled = good.transitions.clone();
    shuffled.swap(5, 6);
    let e = learner
        .update(&Rollout {
            transitions: &shuffled,
            ..good.view()
        })
        .expect_err("env order changes between rows");
    assert!(e.to_string().contains("transition 5"), "{e}");

    let mut nan = good.transitions.clone();
    nan[10].reward = f32::NAN;
    assert!(
        learner
            .update(&Rollout {
                transitions: &nan,
                ..good.view()
            })
            .is_err()
    );

    assert_eq!(learner.policy_weights(), before);
    assert_eq!(learner.counters(), Counters::default());
}

/// SPEC S8: a specialist trains only on its terrain class's transitions that it acted;
/// a chunk with none of them changes nothing.
#[test]
fn a_specialist_trains_only_on_its_terrain_class() {
    let cfg = small_config(64, 10);
    let mut flat = learner(&cfg, 10);
    flat.play(PolicySlot::Flat);
    let mut rollout = OwnedRollout::acted_by(&flat, 16, 4, 11);
    rollout.transitions.iter_mut().for_each(|t| {
        t.estimated_class = 1;
        t.slot = PolicySlot::Flat.index() as u8;
    });
    let before = flat.policy_weights();
    let e = flat
        .update(&rollout.view())
        .expect_err("no flat transitions");
    assert!(e.to_string().contains("other terrain classes"), "{e}");
    assert_eq!(flat.policy_weights(), before, "left unchanged");
    // Flat ground by the estimate, but acted by the rough-terrain model (switching's dwell).
    rollout.transitions[..16].iter_mut().for_each(|t| {
        t.estimated_class = 0;
        t.slot = PolicySlot::Rough.index() as u8;
    });
    flat.update(&rollout.view())
        .expect_err("no flat transitions of its own");
    assert_eq!(flat.policy_weights(), before, "left unchanged");
    rollout.transitions[..16]
        .iter_mut()
        .for_each(|t| t.slot = PolicySlot::Flat.index() as u8);
    flat.update(&rollout.view()).expect("16 flat transitions");
    assert_ne!(flat.policy_weights(), before);
}

/// Async mode: transitions older than `max-policy-lag` versions are not trained on.
#[test]
fn stale_transitions_are_dropped_and_counted() {
    let mut cfg = small_config(64, 10);
    cfg.ppo.max_policy_lag = 1;
    let mut learner = learner(&cfg, 10);
    let mut rollout = OwnedRollout::acted_by(&learner, 16, 4, 11);
    learner.update(&rollout.view()).expect("version 0 -> 1");
    learner.update(&rollout.view()).expect("version 1 -> 2");
    // Rows 0..8 were acted by version 0 (lag 2), the rest by version 2.
    for (i, t) in rollout.transitions.iter_mut().enumerate() {
        t.policy_version = if i < 32 { 0 } else { 2 };
    }
    let m = learner.update(&rollout.view()).expect("update");
    assert_eq!((m.stale_transitions, m.mean_policy_lag), (32, 1.0));
    assert_eq!(m.global_step, 3 * 64);
    rollout
        .transitions
        .iter_mut()
        .for_each(|t| t.policy_version = 0);
    let e = learner.update(&rollout.view()).expect_err("all stale");
    assert!(
        e.to_string().contains("more than 1 policy versions old"),
        "{e}"
    );
}

#[test]
fn learner_can_move_to_another_thread() {
    fn send<T: Send>() {}
    send::<Learner>();
}

#[test]
fn advantage_normalisation_and_diagnostics_by_hand() {
    let mut adv = [1.0f32, 2.0, 3.0];
    normalise_advantages(&mut adv); // mean 2, sample std 1
    assert!((adv[0] + 1.0).abs() < 1e-6 && adv[1].abs() < 1e-6 && (adv[2] - 1.0).abs() < 1e-6);
    let mut one = [5.0f32];
    normalise_advantages(&mut one);
    assert_eq!(one, [5.0]);

    // logratio 0 and ln 1.5: ratios 1 and 1.5.
    let (old_kl, kl, clipfrac) = kl_and_clipfrac(&[0.0, 1.5f32.ln()], 0.2);
    assert!((old_kl + 0.5 * 1.5f64.ln()).abs() < 1e-7);
    assert!((kl - 0.5 * (0.5 - 1.5f64.ln())).abs() < 1e-7);
    assert_eq!(clipfrac, 0.5);

    // returns 1, 2, 3 and values 1, 2, 2: 1 − Var(0, 0, 1)/Var(1, 2, 3) = 1 − (2/9)/(2/3) = 2/3.
    assert!((explained_variance(&[1.0, 2.0, 2.0], &[1.0, 2.0, 3.0]) - 2.0 / 3.0).abs() < 1e-12);
    assert!(explained_variance(&[0.0, 1.0], &[1.0, 1.0]).is_nan());
}
