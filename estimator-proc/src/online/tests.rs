use super::*;
use std::path::PathBuf;

fn config(stay_prob: f64) -> EstimatorConfig {
    EstimatorConfig {
        online_window: 20,
        refit_every: 100,
        pool_size: 4_000,
        stay_prob,
        ..EstimatorConfig::default()
    }
}

/// Two envs, env 0 flat (pitch noise σ 0.02), env 1 rough (σ 0.08).
fn feed(est: &mut OnlineEstimator, ticks: usize, rng: &mut common::Rng) -> Vec<[Estimate; 2]> {
    (0..ticks)
        .map(|_| {
            let a = est.observe(0, 0.02 * rng.normal()).expect("observe");
            let b = est.observe(1, 0.08 * rng.normal()).expect("observe");
            [a, b]
        })
        .collect()
}

#[test]
fn hand_computed_hmm_step() {
    // Belief (½, ½), stay 0.9: prediction stays (½, ½); emissions e^0 and e^−ln 3 = ⅓
    // (relative) give (¾, ¼).
    let mut belief = [0.5, 0.5];
    hmm_forward(&mut belief, &[0.0, -(3f64.ln())], 1.0, 0.9);
    assert!((belief[0] - 0.75).abs() < 1e-12 && (belief[1] - 0.25).abs() < 1e-12);
    // From (1, 0): prediction (0.9, 0.1); equal emissions keep it.
    let mut belief = [1.0, 0.0];
    hmm_forward(&mut belief, &[-5.0, -5.0], 1.0, 0.9);
    assert!((belief[0] - 0.9).abs() < 1e-12);
    // Evidence ½: the ratio 1:⅓ counts as 1:1/√3.
    let mut belief = [0.5, 0.5];
    hmm_forward(&mut belief, &[0.0, -(3f64.ln())], 0.5, 0.9);
    let r = 1.0 / 3f64.sqrt();
    assert!((belief[0] - 1.0 / (1.0 + r)).abs() < 1e-12);
    // A hopeless emission (−1e6 in log space) still leaves a finite, normalised belief.
    let mut belief = [1.0, 0.0];
    hmm_forward(&mut belief, &[-1e6, 0.0], 1.0, 0.98);
    assert!(
        belief.iter().all(|b| b.is_finite()) && (belief.iter().sum::<f64>() - 1.0).abs() < 1e-12
    );
    assert!(belief[1] > 0.999);
}

#[test]
fn pending_until_window_and_first_fit_then_classifies() {
    let mut est = OnlineEstimator::new(&config(0.98), 2, 1).expect("estimator");
    let mut rng = common::Rng::new(3);
    let out = feed(&mut est, 400, &mut rng);
    assert!(out[0][0].class.is_none() && out[0][0].window_std.is_none());
    assert_eq!(out[18][0].window_std, None);
    assert!(out[19][0].window_std.is_some());
    // 50 per component × 2 = 100 pool values: 2 envs fill it 50 ticks after the window
    // fills (tick 19), so the first fit is at tick 68.
    assert!(out[75][0].class.is_some());
    let tail = &out[200..];
    let flat_ok = tail.iter().filter(|e| e[0].class == Some(0)).count();
    let rough_ok = tail.iter().filter(|e| e[1].class == Some(1)).count();
    assert!(flat_ok >= 195 && rough_ok >= 195, "{flat_ok} {rough_ok}");
    assert!(
        tail.iter()
            .all(|e| e[0].posterior > 0.5 && e[0].posterior <= 1.0)
    );
    assert!(est.stats().fits >= 2, "{:?}", est.stats());
}

#[test]
fn a_robot_that_stops_on_rough_ground_keeps_its_rough_estimate() {
    // Window 20 at 0.1 s per tick, min speed 0.02 m/s: a window needs 3.8 cm of path.
    let cfg = config(0.98);
    for gated in [true, false] {
        let mut est = OnlineEstimator::new(&cfg, 2, 3)
            .expect("estimator")
            .gate_stationary(if gated { 0.002 } else { 0.0 });
        let mut rng = common::Rng::new(4);
        // Both drive at 1 cm per tick; env 0 on flat, env 1 on rough ground.
        let mut last = [None, None];
        for t in 0..1_500 {
            let x = 0.01 * f64::from(t);
            let a = est.observe_at(0, 0.02 * rng.normal(), Some([x, 0.0]));
            let b = est.observe_at(1, 0.08 * rng.normal(), Some([x, 1.0]));
            last = [a.expect("observe").class, b.expect("observe").class];
        }
        assert_eq!(last, [Some(0), Some(1)], "classified while driving");
        let pooled = est.pool.values.len();
        // Env 1 wedges on a bump: pitch and position frozen (a hair of jitter).
        for t in 0..300 {
            let x = 0.01 * f64::from(1_500 + t);
            est.observe_at(0, 0.02 * rng.normal(), Some([x, 0.0]))
                .expect("observe");
            let jitter = 1e-5 * rng.normal();
            last[1] = est
                .observe_at(1, -0.12 + jitter, Some([15.0 + jitter, 1.0]))
                .expect("observe")
                .class;
        }
        if gated {
            assert_eq!(last[1], Some(1), "held through the stop");
            // A window is stationary once at most 3 of its 19 steps are driven: after the
            // first 16 ticks of the stop.
            assert_eq!(est.stats().stationary, 300 - 16, "every stopped window");
            assert_eq!(
                est.pool.values.len(),
                pooled + 300 + 16,
                "env 0's, 16 of env 1's"
            );
        } else {
            assert_eq!(last[1], Some(0), "ungated, a still pitch reads as flat");
            assert_eq!(est.stats().stationary, 0);
        }
    }
}

#[test]
fn labels_stay_stable_across_refits_under_drift() {
    // Both terrains get slowly rougher; refits must keep class 0 = the smoother env.
    let cfg = EstimatorConfig {
        stay_prob: 0.0,
        ..config(0.0)
    };
    let mut est = OnlineEstimator::new(&cfg, 2, 2).expect("estimator");
    let mut rng = common::Rng::new(4);
    let mut means = Vec::new();
    for t in 0..3_000 {
        let scale = 1.0 + f64::from(t) / 1_500.0;
        let a = est
            .observe(0, 0.02 * scale * rng.normal())
            .expect("observe");
        let b = est
            .observe(1, 0.08 * scale * rng.normal())
            .expect("observe");
        if t > 200 {
            assert!(a.class.is_some() && b.class.is_some());
        }
        if let Some(m) = est.model() {
            means.push(m.means().to_vec());
        }
    }
    assert!(est.stats().fits >= 25, "{:?}", est.stats());
    assert!(means.iter().all(|m| m[0] < m[1]));
    let last = means.last().expect("fitted");
    assert!(last[0] > 0.03 && last[1] > 0.12, "{last:?}");
}

#[test]
fn hmm_beats_the_raw_classifier_at_a_short_window() {
    let cfg = EstimatorConfig {
        online_window: 10,
        ..config(0.98)
    };
    let mut est = OnlineEstimator::new(&cfg, 2, 5).expect("estimator");
    let mut rng = common::Rng::new(6);
    // Overlapping noise levels make a 10-tick window ambiguous.
    let (mut raw, mut filtered, mut n) = (0, 0, 0);
    for t in 0..4_000 {
        let a = est.observe(0, 0.03 * rng.normal()).expect("observe");
        let b = est.observe(1, 0.05 * rng.normal()).expect("observe");
        if t >= 500 {
            n += 2;
            raw += usize::from(a.raw_class == Some(0)) + usize::from(b.raw_class == Some(1));
            filtered += usize::from(a.class == Some(0)) + usize::from(b.class == Some(1));
        }
    }
    let (raw, filtered) = (raw as f64 / f64::from(n), filtered as f64 / f64::from(n));
    assert!(filtered > raw + 0.05, "filtered {filtered} raw {raw}");
}

#[test]
fn bad_input_is_refused_without_poisoning() {
    let mut est = OnlineEstimator::new(&config(0.98), 1, 1).expect("estimator");
    assert!(matches!(
        est.observe(0, f64::NAN),
        Err(EstimatorError::NonFiniteObservation { env: 0, .. })
    ));
    assert!(matches!(
        est.observe(3, 0.0),
        Err(EstimatorError::EnvOutOfRange { env: 3, envs: 1 })
    ));
    assert!(matches!(
        OnlineEstimator::new(&config(0.98), 0, 1),
        Err(EstimatorError::NoEnvs)
    ));
    // A constant signal: the first fit fails (one distinct value), nothing panics, no NaN.
    for _ in 0..500 {
        let e = est.observe(0, 0.0).expect("observe");
        assert!(e.class.is_none() && e.posterior == 0.0);
        assert_eq!(e.window_std, e.window_std.map(|_| 0.0));
    }
    assert!(est.stats().failed_fits >= 1 && est.stats().fits == 0);
}

#[test]
fn starts_from_a_given_model_and_reset_forgets_the_window() {
    let model = Gmm::new(vec![0.5, 0.5], vec![0.02, 0.08], vec![1e-4, 1e-3]).expect("model");
    let mut est = OnlineEstimator::with_model(&config(0.0), 1, 1, model).expect("estimator");
    let mut rng = common::Rng::new(8);
    let mut last = None;
    for _ in 0..20 {
        last = Some(est.observe(0, 0.15 * rng.normal()).expect("observe"));
    }
    assert_eq!(last.and_then(|e| e.class), Some(1));
    est.reset_env(0).expect("reset");
    assert!(est.observe(0, 0.0).expect("observe").window_std.is_none());
    assert!(est.reset_env(1).is_err());
}

/// A window carried across a placement: the pitch window and the estimate run on, and the
/// jump is no path, so a robot placed 5 m away counts as moving as before.
#[test]
fn a_carried_window_runs_on_across_a_jump() {
    let model = Gmm::new(vec![0.5, 0.5], vec![0.02, 0.08], vec![1e-4, 1e-3]).expect("model");
    // No refit: one would land between the two envs' observations of a tick.
    let cfg = EstimatorConfig {
        refit_every: 0,
        ..config(0.0)
    };
    let est = OnlineEstimator::with_model(&cfg, 2, 1, model).expect("estimator");
    // Driving 1 cm a tick; the gate wants 0.9 cm a tick over the window.
    let mut est = est.gate_stationary(0.009);
    let mut rng = common::Rng::new(3);
    for t in 0..100 {
        let p = 0.08 * rng.normal();
        let x = 0.01 * f64::from(t);
        let jumped = if t >= 80 { x + 5.0 } else { x };
        if t == 80 {
            est.jump_env(1).expect("jump");
        }
        let [a, b] = [(0, x), (1, jumped)]
            .map(|(env, x)| est.observe_at(env, p, Some([x, 0.0])).expect("observe"));
        assert_eq!(a, b, "tick {t}");
    }
    assert_eq!(est.stats().stationary, 0);
    assert!(est.jump_env(2).is_err());
}

/// A mixture over log std classifies each window by the log of its std: windows of
/// std 0.02 and 0.08 fall to components at ln 0.02 and ln 0.08.
#[test]
fn a_log_std_model_classifies_the_log_of_each_window() {
    let dir = tempfile::tempdir().expect("tempdir");
    let results = dir.path().join("results.json");
    let (flat, rough) = (0.02f64.ln(), 0.08f64.ln());
    let fit = format!(
        r#"{{"window": 20, "feature": "log-std", "weights": [0.5, 0.5], "means": [{flat}, {rough}], "stds": [0.3, 0.3]}}"#
    );
    std::fs::write(&results, format!(r#"{{"windows": [{fit}]}}"#)).expect("write");
    let cfg = EstimatorConfig {
        model: Some(results),
        refit_every: 0,
        feature: MixtureFeature::LogStd,
        ..config(0.0)
    };
    let mut est = OnlineEstimator::from_config(&cfg, 2, 1).expect("estimator");
    let mut rng = common::Rng::new(4);
    let mut last = [None; 2];
    for _ in 0..200 {
        for (env, scale) in [(0, 0.02), (1, 0.08)] {
            last[env] = est
                .observe(env, scale * rng.normal())
                .expect("observe")
                .class;
        }
    }
    assert_eq!(last, [Some(0), Some(1)]);
}

/// SPEC S7: with `refit-every = 0` the offline model classifies throughout, so one
/// terrain alone (here rough) stays one class; fitted online from scratch, the first fit
/// splits it into two.
#[test]
fn an_offline_model_keeps_one_terrain_in_one_class() {
    let dir = tempfile::tempdir().expect("tempdir");
    let results = dir.path().join("results.json");
    let fit =
        r#"{"window": 20, "weights": [0.5, 0.5], "means": [0.02, 0.08], "stds": [0.01, 0.03]}"#;
    std::fs::write(&results, format!(r#"{{"windows": [{fit}]}}"#)).expect("write");
    let mut rng = common::Rng::new(9);
    let mut rough_share = |model: Option<PathBuf>| {
        let cfg = EstimatorConfig {
            model,
            refit_every: 0,
            ..config(0.0)
        };
        let mut est = OnlineEstimator::from_config(&cfg, 2, 1).expect("estimator");
        let mut rough = 0;
        for _ in 0..3000 {
            for env in 0..2 {
                let e = est.observe(env, 0.08 * rng.normal()).expect("observe");
                rough += usize::from(e.class == Some(1));
            }
        }
        (rough as f64 / 6000.0, est.stats().fits)
    };
    let (share, fits) = rough_share(Some(results.clone()));
    assert_eq!(fits, 0, "never refitted");
    assert!(share > 0.95, "rough share {share}");
    let (share, fits) = rough_share(None);
    assert_eq!(fits, 1, "fitted once");
    // Its lower component is cut from the rough values (here a tenth of them).
    assert!(
        share < 0.93,
        "rough alone split in two: rough share {share}"
    );
}
