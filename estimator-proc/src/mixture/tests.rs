use super::*;
use crate::kinds;

fn opts(components: usize, covariance: Covariance) -> MixtureOptions {
    MixtureOptions {
        em: crate::gmm::FitOptions {
            components,
            restarts: 5,
            max_iter: 500,
            tol: 1e-8,
            var_floor: 1e-10,
            equal_weights: false,
            seed: 7,
        },
        covariance,
    }
}

/// `per_class` points of each class around `means` (2-D), unit std on both axes; class 1's
/// axes correlate (ρ = 0.6). Returns the points, row-major, and their labels.
fn three_classes(per_class: usize, means: [[f64; 2]; 3], seed: u64) -> (Vec<f64>, Vec<usize>) {
    let mut rng = common::Rng::new(seed);
    let (mut data, mut labels) = (Vec::new(), Vec::new());
    for (k, m) in means.iter().enumerate() {
        for _ in 0..per_class {
            let (a, b) = (rng.normal(), rng.normal());
            let (x, y) = if k == 1 {
                (a, 0.6 * a + 0.8 * b)
            } else {
                (a, b)
            };
            data.extend([m[0] + x, m[1] + y]);
            labels.push(k);
        }
    }
    (data, labels)
}

fn confusion(model: &Mixture, data: &[f64], labels: &[usize], kinds: usize) -> Vec<Vec<u64>> {
    let mut c = vec![vec![0u64; model.components()]; kinds];
    for (p, &k) in data.chunks_exact(2).zip(labels) {
        c[k][model.classify(p)] += 1;
    }
    c
}

#[test]
fn three_classes_four_sigma_apart_are_recovered_and_named() {
    // Each pair of means is 4σ apart along each axis (5.7σ in the plane): the Bayes rule errs
    // on about 0.3 % of points.
    let means = [[0.0, 0.0], [4.0, 4.0], [8.0, 0.0]];
    let (data, labels) = three_classes(1000, means, 11);
    for covariance in [Covariance::Full, Covariance::Diagonal] {
        let fit = fit(&data, 2, &opts(3, covariance)).expect("fit");
        assert!(fit.converged, "{covariance:?}");
        let c = confusion(&fit.model, &data, &labels, 3);
        let kind_of = kinds::assign(&c);
        let by_kind = kinds::kind_confusion(&c, &kind_of);
        let accuracy = kinds::macro_accuracy(&by_kind);
        assert!(accuracy > 0.99, "{covariance:?}: {accuracy} {by_kind:?}");
        // The fitted means, back in raw units, are the true ones.
        for (c, &k) in kind_of.iter().enumerate() {
            let m: Vec<f64> = (0..2)
                .map(|f| fit.model.centre[f] + fit.model.scale[f] * fit.model.means[c][f])
                .collect();
            assert!(
                (m[0] - means[k][0]).abs() < 0.15 && (m[1] - means[k][1]).abs() < 0.15,
                "{covariance:?}: component {c} at {m:?}, kind {k} at {:?}",
                means[k]
            );
        }
    }
}

#[test]
fn the_full_covariance_finds_the_correlation_the_diagonal_one_cannot() {
    let (data, _) = three_classes(1000, [[0.0, 0.0], [6.0, 6.0], [12.0, 0.0]], 5);
    let full = fit(&data, 2, &opts(3, Covariance::Full)).expect("full");
    let diagonal = fit(&data, 2, &opts(3, Covariance::Diagonal)).expect("diagonal");
    // Component 1 (middle by first feature) is the correlated class: ρ = 0.6.
    let rho = |m: &Mixture| {
        let c = &m.covs[1];
        c[1] / (c[0] * c[3]).sqrt()
    };
    assert!(
        (rho(&full.model) - 0.6).abs() < 0.05,
        "{}",
        rho(&full.model)
    );
    assert_eq!(rho(&diagonal.model), 0.0);
    assert!(full.log_likelihood > diagonal.log_likelihood);
}

#[test]
fn relabelled_truth_gives_the_same_fit_and_a_permuted_naming() {
    let (data, labels) = three_classes(500, [[0.0, 0.0], [4.0, 4.0], [8.0, 0.0]], 3);
    let model = fit(&data, 2, &opts(3, Covariance::Full))
        .expect("fit")
        .model;
    let named = kinds::assign(&confusion(&model, &data, &labels, 3));
    let perm = [2, 0, 1];
    let relabelled: Vec<usize> = labels.iter().map(|&k| perm[k]).collect();
    let renamed = kinds::assign(&confusion(&model, &data, &relabelled, 3));
    for c in 0..3 {
        assert_eq!(renamed[c], perm[named[c]], "{named:?} → {renamed:?}");
    }
}

#[test]
fn a_window_no_component_explains_is_unknown() {
    let (data, _) = three_classes(500, [[0.0, 0.0], [4.0, 4.0], [8.0, 0.0]], 9);
    let model = fit(&data, 2, &opts(3, Covariance::Full))
        .expect("fit")
        .model;
    assert!(model.classify_or_unknown(&[0.1, -0.2], 4.0).is_some());
    assert_eq!(model.classify_or_unknown(&[4.0, -8.0], 4.0), None);
    // 0 never refuses.
    assert!(model.classify_or_unknown(&[4.0, -8.0], 0.0).is_some());
}

#[test]
fn bad_data_is_refused_with_the_reason() {
    let o = opts(2, Covariance::Full);
    assert!(matches!(
        fit(&[1.0, f64::NAN, 2.0, 3.0], 2, &o),
        Err(EstimatorError::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        fit(&[1.0, 2.0, 3.0], 2, &o),
        Err(EstimatorError::InvalidModel { .. })
    ));
    // A constant second feature cannot be standardised.
    assert!(matches!(
        fit(&[1.0, 5.0, 2.0, 5.0, 3.0, 5.0], 2, &o),
        Err(EstimatorError::Degenerate { .. })
    ));
}

#[test]
fn a_model_survives_a_round_trip_through_json() {
    let (data, _) = three_classes(200, [[0.0, 0.0], [4.0, 4.0], [8.0, 0.0]], 2);
    let model = fit(&data, 2, &opts(3, Covariance::Full))
        .expect("fit")
        .model;
    let text = serde_json::to_string(&model).expect("json");
    let back: Mixture = serde_json::from_str(&text).expect("parse");
    for p in data.chunks_exact(2) {
        assert_eq!(back.classify(p), model.classify(p));
    }
    // A stored model is validated as it is read.
    let broken = text.replacen("\"weights\":[", "\"weights\":[-", 1);
    let e = serde_json::from_str::<Mixture>(&broken).expect_err("negative weight");
    assert!(e.to_string().contains("invalid mixture"), "{e}");
}

#[test]
fn a_labelled_fit_is_each_labels_own_gaussian() {
    // Label 0: a 2 × 2 square around (1, 1), variance 1 on each axis, no covariance. Label 1:
    // the same square around (11, 1) plus its centre: mean (11, 1), variance 4/5.
    let square = |cx: f64| [cx - 1.0, 0.0, cx + 1.0, 0.0, cx - 1.0, 2.0, cx + 1.0, 2.0];
    let mut data = square(1.0).to_vec();
    data.extend(square(11.0));
    data.extend([11.0, 1.0]);
    let labels = [0, 0, 0, 0, 1, 1, 1, 1, 1];
    let fit = fit_labelled(&data, 2, &labels, &opts(2, Covariance::Full)).expect("fit");
    let m = &fit.model;
    let raw_mean = |c: usize, f: usize| m.centre[f] + m.scale[f] * m.means[c][f];
    let raw_cov = |c: usize, a: usize, b: usize| m.covs[c][a * 2 + b] * m.scale[a] * m.scale[b];
    // The variance floor (1e-10 in standardised units) adds a few 1e-9 to each raw variance.
    let close = |x: f64, y: f64| (x - y).abs() < 1e-7;
    // Stored sorted by the first feature's mean: label 0 first.
    for (c, (mx, var, weight)) in [(1.0, 1.0, 4.0 / 9.0), (11.0, 0.8, 5.0 / 9.0)]
        .into_iter()
        .enumerate()
    {
        assert!(
            close(raw_mean(c, 0), mx) && close(raw_mean(c, 1), 1.0),
            "{c}"
        );
        assert!(
            close(raw_cov(c, 0, 0), var) && close(raw_cov(c, 1, 1), var),
            "{c}"
        );
        assert!(close(raw_cov(c, 0, 1), 0.0), "{c}");
        assert!(close(m.weights[c], weight), "{c}");
    }
    assert_eq!((fit.iterations, fit.restarts_ok), (0, 1));
    let bad = fit_labelled(
        &data,
        2,
        &[0, 0, 0, 0, 1, 1, 1, 1, 2],
        &opts(2, Covariance::Full),
    );
    assert!(bad.is_err());
}

#[test]
fn a_labelled_fit_keeps_a_class_of_two_clusters_in_one_component() {
    // Label 0 is two clusters 12σ apart, label 1 one cluster midway between them. Each
    // label's one Gaussian (σx² ≈ 37 and 1 about the same mean) draws the boundary at
    // x² (1/2 − 1/74) = ½ ln 37, |x| ≈ 1.93: about 5.4 % of label 1 falls beyond it and
    // none of label 0, a macro accuracy near 97.3 %.
    let mut rng = common::Rng::new(3);
    let (mut data, mut labels) = (Vec::new(), Vec::new());
    for (x, label) in [(-6.0, 0), (6.0, 0), (0.0, 1), (0.0, 1)] {
        for _ in 0..500 {
            data.extend([x + rng.normal(), rng.normal()]);
            labels.push(label);
        }
    }
    let fit = fit_labelled(&data, 2, &labels, &opts(2, Covariance::Full)).expect("fit");
    let c = confusion(&fit.model, &data, &labels, 2);
    let by_kind = kinds::kind_confusion(&c, &kinds::assign(&c));
    let accuracy = kinds::macro_accuracy(&by_kind);
    assert!(accuracy > 0.96, "{accuracy} {by_kind:?}");
}
