use super::*;
use proptest::prelude::*;

fn opts(components: usize) -> FitOptions {
    FitOptions::from_config(
        &EstimatorConfig {
            components,
            ..EstimatorConfig::default()
        },
        7,
    )
}

/// `n` draws from the mixture (weights, means, stds).
fn sample(n: usize, w: &[f64], mu: &[f64], sd: &[f64], seed: u64) -> Vec<f64> {
    let mut rng = common::Rng::new(seed);
    (0..n)
        .map(|_| {
            let u = rng.uniform();
            let mut acc = 0.0;
            let k = w
                .iter()
                .position(|&wk| {
                    acc += wk;
                    u < acc
                })
                .unwrap_or(w.len() - 1);
            mu[k] + sd[k] * rng.normal()
        })
        .collect()
}

#[test]
fn recovers_a_known_two_component_mixture() {
    let (w, mu, sd) = ([0.4, 0.6], [0.03, 0.09], [0.01, 0.03]);
    let data = sample(10_000, &w, &mu, &sd, 1);
    let r = fit(&data, &opts(2)).expect("fit");
    let m = &r.model;
    for k in 0..2 {
        assert!(
            ((m.means()[k] - mu[k]) / mu[k]).abs() < 0.02,
            "means {:?}",
            m.means()
        );
        assert!(
            (m.weights()[k] - w[k]).abs() < 0.02,
            "weights {:?}",
            m.weights()
        );
        assert!(
            ((m.stds()[k] - sd[k]) / sd[k]).abs() < 0.1,
            "stds {:?}",
            m.stds()
        );
    }
    assert!(r.converged);
    assert_eq!(r.restarts_ok, 5);
}

#[test]
fn log_likelihood_never_decreases() {
    // Overlapping components make EM take many small steps.
    let data = sample(
        3_000,
        &[0.5, 0.3, 0.2],
        &[0.0, 1.0, 2.5],
        &[0.6, 0.5, 0.8],
        2,
    );
    for restart_seed in 0..4 {
        let o = FitOptions {
            seed: restart_seed,
            restarts: 1,
            ..opts(3)
        };
        let r = fit(&data, &o).expect("fit");
        assert!(r.history.len() > 5, "{} iterations", r.history.len());
        for pair in r.history.windows(2) {
            assert!(pair[1] >= pair[0] - 1e-9 * pair[0].abs(), "{pair:?}");
        }
    }
}

#[test]
fn hand_computed_e_step_and_m_step() {
    // Data 0, 1, 2; start w = (½, ½), μ = (0, 2), σ² = (1, 1).
    // For x = 0 the log-odds of component 0 are ((0−2)² − 0²)/2 = 2, so r₀ = a = e²/(1+e²);
    // x = 1 is equidistant (r₀ = ½); x = 2 mirrors x = 0 (r₀ = 1 − a).
    let m = Gmm::new(vec![0.5, 0.5], vec![0.0, 2.0], vec![1.0, 1.0]).expect("model");
    let data = [0.0, 1.0, 2.0];
    let e = m.e_step(&data);
    let a = 2f64.exp() / (1.0 + 2f64.exp());
    let b = 1.0 - a;
    assert!((e.stats.n[0] - 1.5).abs() < 1e-12 && (e.stats.n[1] - 1.5).abs() < 1e-12);
    // ln p(0) = ln(½ φ(0) + ½ φ(2)) with φ the standard normal density; p(2) = p(0).
    let phi = |x: f64| (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let ll = 2.0 * (0.5 * phi(0.0) + 0.5 * phi(2.0)).ln() + phi(1.0).ln();
    assert!(
        (e.log_likelihood - ll).abs() < 1e-12,
        "{} vs {ll}",
        e.log_likelihood
    );
    let next = Gmm::m_step(&e.stats, 1e-10, false).expect("m-step");
    let mean0 = (0.5 + 2.0 * b) / 1.5;
    let var0 = (a * mean0.powi(2) + 0.5 * (1.0 - mean0).powi(2) + b * (2.0 - mean0).powi(2)) / 1.5;
    assert!((next.weights()[0] - 0.5).abs() < 1e-12);
    assert!(
        (next.means()[0] - mean0).abs() < 1e-12,
        "{} vs {mean0}",
        next.means()[0]
    );
    assert!((next.means()[1] - (2.0 - mean0)).abs() < 1e-12);
    assert!(
        (next.variances()[0] - var0).abs() < 1e-12,
        "{} vs {var0}",
        next.variances()[0]
    );
    assert!((next.variances()[1] - var0).abs() < 1e-12);
}

#[test]
fn far_out_points_do_not_underflow() {
    // Every component's density underflows to 0 at x = 1e3 in linear space.
    let m = Gmm::new(vec![0.5, 0.5], vec![0.0, 1.0], vec![1e-4, 1e-4]).expect("model");
    let mut post = [0.0; 2];
    let lp = m.posteriors(1e3, &mut post);
    assert!(lp.is_finite() && lp < -1e9);
    assert_eq!(post, [0.0, 1.0]);
    assert_eq!(m.classify(1e3), 1);
    assert!(m.e_step(&[1e3, -1e3, 0.5]).log_likelihood.is_finite());
}

#[test]
fn degenerate_inputs_give_errors() {
    let o = opts(2);
    assert!(matches!(
        fit(&[0.1, f64::NAN, 0.2], &o),
        Err(EstimatorError::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        fit(&[0.1, f64::INFINITY], &o),
        Err(EstimatorError::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        fit(&[0.1], &o),
        Err(EstimatorError::TooFewPoints {
            n: 1,
            components: 2
        })
    ));
    assert!(matches!(
        fit(&[], &o),
        Err(EstimatorError::TooFewPoints { n: 0, .. })
    ));
    let e = fit(&[0.05; 100], &o).expect_err("constant");
    assert!(matches!(
        e,
        EstimatorError::Degenerate {
            distinct: 1,
            components: 2
        }
    ));
    assert!(!e.to_string().contains('\n'));
    // Two distinct values are enough for two components: the floor keeps it finite.
    let r = fit(&[0.0, 0.0, 1.0, 1.0, 1.0], &o).expect("two values");
    assert!(r.log_likelihood.is_finite());
    assert!(r.model.variances().iter().all(|&v| v >= o.var_floor));
}

#[test]
fn invalid_models_are_refused() {
    assert!(Gmm::new(vec![0.5, 0.6], vec![0.0, 1.0], vec![1.0, 1.0]).is_err());
    assert!(Gmm::new(vec![0.5, 0.5], vec![0.0, f64::NAN], vec![1.0, 1.0]).is_err());
    assert!(Gmm::new(vec![0.5, 0.5], vec![0.0, 1.0], vec![1.0, 0.0]).is_err());
    assert!(Gmm::new(vec![1.0], vec![0.0, 1.0], vec![1.0]).is_err());
}

#[test]
fn labels_are_ordered_by_mean() {
    let m = Gmm::new(vec![0.7, 0.3], vec![0.09, 0.02], vec![4e-4, 1e-4]).expect("model");
    assert_eq!(m.means(), &[0.02, 0.09]);
    assert_eq!(m.weights(), &[0.3, 0.7]);
    assert_eq!(m.variances(), &[1e-4, 4e-4]);
    let data = sample(
        2_000,
        &[0.2, 0.3, 0.5],
        &[5.0, -3.0, 1.0],
        &[0.5, 0.5, 0.5],
        4,
    );
    for seed in 0..5 {
        let r = fit(&data, &FitOptions { seed, ..opts(3) }).expect("fit");
        assert!(
            r.model.means().windows(2).all(|p| p[0] < p[1]),
            "{:?}",
            r.model.means()
        );
        assert!((r.model.means()[0] + 3.0).abs() < 0.1);
    }
}

#[test]
fn equal_weights_hold_one_over_k_and_em_still_climbs() {
    // 60 % of the points around 0, 40 % around 5: free weights find 0.6 / 0.4; held at
    // one half each, the means still find both clusters (at 90 / 10 they would split
    // the larger one instead: equal weights suit data drawn about equally).
    let data = sample(4_000, &[0.6, 0.4], &[0.0, 5.0], &[1.0, 1.0], 6);
    let free = fit(&data, &opts(2)).expect("free");
    assert!((free.model.weights()[0] - 0.6).abs() < 0.03);
    let held = fit(
        &data,
        &FitOptions {
            equal_weights: true,
            ..opts(2)
        },
    )
    .expect("held");
    assert_eq!(held.model.weights(), &[0.5, 0.5]);
    assert!(
        (held.model.means()[0]).abs() < 0.1,
        "{:?}",
        held.model.means()
    );
    assert!(
        (held.model.means()[1] - 5.0).abs() < 0.1,
        "{:?}",
        held.model.means()
    );
    assert!(held.history.windows(2).all(|p| p[1] >= p[0] - 1e-9));
    assert!(held.log_likelihood < free.log_likelihood);
}

#[test]
fn warm_start_keeps_component_identity() {
    let data = sample(5_000, &[0.5, 0.5], &[0.03, 0.1], &[0.01, 0.03], 5);
    let first = fit(&data, &opts(2)).expect("fit");
    let shifted: Vec<f64> = data.iter().map(|x| x + 0.005).collect();
    let again = fit_from(&shifted, &first.model, &opts(2)).expect("refit");
    for k in 0..2 {
        assert!((again.model.means()[k] - first.model.means()[k] - 0.005).abs() < 2e-3);
    }
}

proptest! {
    #[test]
    fn fitted_weights_sum_to_one_and_params_are_finite(
        data in prop::collection::vec(-10.0f64..10.0, 2..200),
        k in 2usize..4,
    ) {
        match fit(&data, &FitOptions { max_iter: 50, ..opts(k) }) {
            Ok(r) => {
                let m = &r.model;
                prop_assert!((m.weights().iter().sum::<f64>() - 1.0).abs() < 1e-9);
                prop_assert!(m.means().iter().chain(m.variances()).all(|v| v.is_finite()));
                prop_assert!(m.means().windows(2).all(|p| p[0] <= p[1]));
                prop_assert!(r.log_likelihood.is_finite());
            }
            Err(e) => prop_assert!(
                matches!(e, EstimatorError::TooFewPoints { .. } | EstimatorError::Degenerate { .. } | EstimatorError::NoFit { .. }),
                "{}", e
            ),
        }
    }
}
