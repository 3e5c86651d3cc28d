//! Naming a mixture's components after terrain kinds, and scoring a K-kind classifier on a
//! labelled recording (`estimator-proc kinds`).
//!
//! With one feature SPEC S7 calls the lowest-mean component "flat"; with several features and
//! kinds no order names them. A labelled collection does: its confusion matrix (true kind ×
//! component) gives, for every one-to-one assignment of components to kinds, how many windows
//! it would classify right, and the Hungarian method finds the best in O(K³). Components
//! beyond the number of kinds (a kind split in two) go to the kind most of their windows
//! have.

use crate::features::FeatureWindows;
use crate::gmm::{self, Gmm};
use crate::mixture::{self, Mixture, MixtureOptions};
use crate::{EstimatorError, Result};
use common::AreaKind;
use common::config::{KindsFit, WindowFeature};
use serde::{Deserialize, Serialize};

/// A fitted classifier of windows: with one feature SPEC S7's 1-D mixture ([`crate::gmm`],
/// so one feature reproduces the paper's analysis exactly), with several the d-dimensional
/// one ([`crate::mixture`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Classifier {
    OneFeature(Gmm),
    Several(Mixture),
}

impl Classifier {
    /// Fits `windows` with `opts`' components and EM settings: without their labels, or,
    /// given `labels` (each window's component), one component per label fitted to its own
    /// windows ([`mixture::fit_labelled`], with any number of features).
    pub fn fit(
        windows: &FeatureWindows,
        opts: &MixtureOptions,
        labels: Option<&[usize]>,
    ) -> Result<(Self, f64, usize, bool)> {
        let several = |f: mixture::MixtureFit| {
            (
                Self::Several(f.model),
                f.log_likelihood,
                f.iterations,
                f.converged,
            )
        };
        match labels {
            Some(labels) => {
                mixture::fit_labelled(&windows.values, windows.dim, labels, opts).map(several)
            }
            None if windows.dim == 1 => {
                let f = gmm::fit(&windows.values, &opts.em)?;
                Ok((
                    Self::OneFeature(f.model),
                    f.log_likelihood,
                    f.iterations,
                    f.converged,
                ))
            }
            None => mixture::fit(&windows.values, windows.dim, opts).map(several),
        }
    }

    pub fn components(&self) -> usize {
        match self {
            Self::OneFeature(g) => g.components(),
            Self::Several(m) => m.components(),
        }
    }

    /// The most probable component of a window's features `x`.
    pub fn classify(&self, x: &[f64]) -> usize {
        match self {
            Self::OneFeature(g) => g.classify(x[0]),
            Self::Several(m) => m.classify(x),
        }
    }

    /// The most probable component of a window's features `x` and its posterior.
    pub fn posterior(&self, x: &[f64]) -> (usize, f64) {
        let mut p = vec![0.0; self.components()];
        match self {
            Self::OneFeature(g) => {
                g.posteriors(x[0], &mut p);
            }
            Self::Several(m) => {
                let mut z = vec![0.0; x.len()];
                m.standardise(x, &mut z);
                let lse = m.joint_log(&z, &mut p);
                p.iter_mut().for_each(|v| *v = (*v - lse).exp());
            }
        }
        let c = (0..p.len()).fold(0, |b, c| if p[c] > p[b] { c } else { b });
        (c, p[c])
    }

    /// Whether some component explains `x`: within `beyond` standard deviations
    /// (Mahalanobis) of its mean; 0 accepts every window.
    pub fn explains(&self, x: &[f64], beyond: f64) -> bool {
        if beyond <= 0.0 {
            return true;
        }
        match self {
            Self::OneFeature(g) => g
                .means()
                .iter()
                .zip(g.stds())
                .any(|(m, s)| (x[0] - m).abs() <= beyond * s),
            Self::Several(m) => m.classify_or_unknown(x, beyond).is_some(),
        }
    }
}

/// A K-kind classifier fitted to a labelled recording's windows, or read from a model file,
/// its components named after kinds, and its score on a recording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KindsResult {
    pub window: usize,
    pub features: Vec<WindowFeature>,
    /// The kinds scored: the rows of `confusion`, the columns before "unknown".
    pub kinds: Vec<AreaKind>,
    pub n: usize,
    pub stationary: usize,
    /// How EM ended, when the model was fitted here (not with `--model`).
    pub fit: Option<FitSummary>,
    /// The kind each component stands for ([`assign`]).
    pub component_kinds: Vec<AreaKind>,
    /// `confusion[true][given]` over `kinds`, then a last column of unknown windows.
    pub confusion: Vec<Vec<u64>>,
    /// Windows classified right over all windows.
    pub accuracy: f64,
    /// The mean over kinds of each one's share classified right ([`macro_accuracy`]).
    pub macro_accuracy: f64,
    pub unknown: u64,
    pub model: Classifier,
}

/// How a fit ended.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitSummary {
    pub log_likelihood: f64,
    pub iterations: usize,
    pub converged: bool,
}

/// A named classifier as `kinds.json` stores it (one per window size), for scoring another
/// recording with it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct StoredKinds {
    pub window: usize,
    pub features: Vec<WindowFeature>,
    pub component_kinds: Vec<AreaKind>,
    pub model: Classifier,
}

/// What `kinds.json` holds of its classifiers.
#[derive(Debug, Deserialize)]
struct StoredReport {
    windows: Vec<StoredKinds>,
}

/// Every named classifier in the `kinds.json` at `path`.
pub fn read_stored(path: &std::path::Path) -> anyhow::Result<Vec<StoredKinds>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("cannot read the model {}: {e}", path.display()))?;
    let stored: StoredReport = serde_json::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: not a kinds.json model: {e}", path.display()))?;
    if stored.windows.is_empty() {
        anyhow::bail!("{}: holds no model", path.display());
    }
    Ok(stored.windows)
}

/// Fits `windows` as `how` says, names the components after the recording's `kinds` by
/// the labels, and scores every window; those farther than `beyond` σ from every component
/// are unknown. A labelled fit takes one component per kind.
pub fn fit_and_name(
    windows: &FeatureWindows,
    window: usize,
    features: &[WindowFeature],
    kinds: &[AreaKind],
    (opts, how): (&MixtureOptions, KindsFit),
    beyond: f64,
) -> Result<KindsResult> {
    let labels: Option<Vec<usize>> = match how {
        KindsFit::Em => None,
        KindsFit::Labelled if opts.em.components != kinds.len() => {
            return Err(EstimatorError::InvalidModel {
                reason: format!(
                    "a labelled fit takes one component per kind: {} kinds, {} components",
                    kinds.len(),
                    opts.em.components
                ),
            });
        }
        KindsFit::Labelled => Some(
            windows
                .kinds
                .iter()
                .map(|k| kinds.iter().position(|x| x == k).unwrap_or(kinds.len()))
                .collect(),
        ),
    };
    let (model, log_likelihood, iterations, converged) =
        Classifier::fit(windows, opts, labels.as_deref())?;
    let classes = classes(&model, windows, beyond);
    let row = |k: &AreaKind| kinds.iter().position(|x| x == k);
    let mut by_component = vec![vec![0u64; model.components()]; kinds.len()];
    for (class, kind) in classes.iter().zip(&windows.kinds) {
        if let (Some(c), Some(k)) = (class, row(kind)) {
            by_component[k][*c] += 1;
        }
    }
    let named = StoredKinds {
        window,
        features: features.to_vec(),
        component_kinds: assign(&by_component).iter().map(|&k| kinds[k]).collect(),
        model,
    };
    let mut result = score(named, windows, &classes, kinds);
    result.fit = Some(FitSummary {
        log_likelihood,
        iterations,
        converged,
    });
    Ok(result)
}

/// Scores a stored, named classifier on `windows` (computed with its features): every kind
/// of the recording or of the model is a row.
pub fn score_stored(stored: StoredKinds, windows: &FeatureWindows, beyond: f64) -> KindsResult {
    let classes = classes(&stored.model, windows, beyond);
    let kinds: Vec<AreaKind> = AreaKind::KINDS
        .into_iter()
        .filter(|k| windows.kinds.contains(k) || stored.component_kinds.contains(k))
        .collect();
    score(stored, windows, &classes, &kinds)
}

/// Each window's component, `None` when none explains it.
fn classes(model: &Classifier, windows: &FeatureWindows, beyond: f64) -> Vec<Option<usize>> {
    windows
        .values
        .chunks_exact(windows.dim)
        .map(|x| model.explains(x, beyond).then(|| model.classify(x)))
        .collect()
}

fn score(
    named: StoredKinds,
    windows: &FeatureWindows,
    classes: &[Option<usize>],
    kinds: &[AreaKind],
) -> KindsResult {
    let row = |k: &AreaKind| kinds.iter().position(|x| x == k);
    let mut confusion = vec![vec![0u64; kinds.len() + 1]; kinds.len()];
    for (class, kind) in classes.iter().zip(&windows.kinds) {
        if let Some(k) = row(kind) {
            let given = class
                .and_then(|c| row(&named.component_kinds[c]))
                .unwrap_or(kinds.len());
            confusion[k][given] += 1;
        }
    }
    let right: u64 = (0..kinds.len()).map(|k| confusion[k][k]).sum();
    KindsResult {
        window: named.window,
        features: named.features,
        kinds: kinds.to_vec(),
        n: windows.len(),
        stationary: windows.stationary,
        fit: None,
        component_kinds: named.component_kinds,
        accuracy: right as f64 / windows.len().max(1) as f64,
        macro_accuracy: macro_accuracy(&confusion),
        unknown: classes.iter().filter(|c| c.is_none()).count() as u64,
        confusion,
        model: named.model,
    }
}

/// `kind_of[c]`: the kind (row of `confusion`) component `c` (column) stands for, chosen to
/// maximise the windows classified right. `confusion[kind][component]` counts windows.
pub fn assign(confusion: &[Vec<u64>]) -> Vec<usize> {
    let kinds = confusion.len();
    let components = confusion.first().map_or(0, Vec::len);
    let n = kinds.max(components);
    // Cost of giving component j kind i: minus the windows that would be right (padded 0).
    let cost = |i: usize, j: usize| -> i64 {
        if i < kinds && j < components {
            -(confusion[i][j] as i64)
        } else {
            0
        }
    };
    let row_of = hungarian(n, cost);
    (0..components)
        .map(|j| {
            let i = row_of[j];
            if i < kinds {
                i
            } else {
                (0..kinds).max_by_key(|&k| confusion[k][j]).unwrap_or(0)
            }
        })
        .collect()
}

/// The minimum-cost perfect matching of an `n × n` cost matrix (rows to columns), by the
/// Hungarian method with potentials: returns the row matched to each column.
fn hungarian(n: usize, cost: impl Fn(usize, usize) -> i64) -> Vec<usize> {
    // 1-based arrays; `matched[j]` is the row (1..=n) of column j, 0 for none.
    let (mut u, mut v) = (vec![0i64; n + 1], vec![0i64; n + 1]);
    let (mut matched, mut way) = (vec![0usize; n + 1], vec![0usize; n + 1]);
    for row in 1..=n {
        matched[0] = row;
        let mut col = 0;
        let mut min = vec![i64::MAX; n + 1];
        let mut used = vec![false; n + 1];
        loop {
            used[col] = true;
            let i = matched[col];
            let (mut delta, mut next) = (i64::MAX, 0);
            for j in 1..=n {
                if !used[j] {
                    let reduced = cost(i - 1, j - 1) - u[i] - v[j];
                    if reduced < min[j] {
                        min[j] = reduced;
                        way[j] = col;
                    }
                    if min[j] < delta {
                        delta = min[j];
                        next = j;
                    }
                }
            }
            for j in 0..=n {
                if used[j] {
                    u[matched[j]] += delta;
                    v[j] -= delta;
                } else {
                    min[j] -= delta;
                }
            }
            col = next;
            if matched[col] == 0 {
                break;
            }
        }
        while col != 0 {
            let prev = way[col];
            matched[col] = matched[prev];
            col = prev;
        }
    }
    (1..=n).map(|j| matched[j] - 1).collect()
}

/// The confusion of predicted kinds: `by_kind[true][predicted]`, from the component confusion
/// and the assignment.
#[cfg(test)]
pub fn kind_confusion(confusion: &[Vec<u64>], kind_of: &[usize]) -> Vec<Vec<u64>> {
    let kinds = confusion.len();
    confusion
        .iter()
        .map(|row| {
            let mut out = vec![0u64; kinds];
            for (c, &count) in row.iter().enumerate() {
                out[kind_of[c]] += count;
            }
            out
        })
        .collect()
}

/// The mean over kinds (rows) of each kind's share of windows classified right (kinds with no
/// windows left out): every kind counts alike however many windows it has. A row may have
/// more columns than kinds (e.g. unknown windows): they count as wrong.
pub fn macro_accuracy(by_kind: &[Vec<u64>]) -> f64 {
    let recalls: Vec<f64> = by_kind
        .iter()
        .enumerate()
        .filter_map(|(k, row)| {
            let total: u64 = row.iter().sum();
            (total > 0).then(|| row[k] as f64 / total as f64)
        })
        .collect();
    recalls.iter().sum::<f64>() / recalls.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{analyze_window, split_series};
    use crate::features::{Wheels, window_features};
    use common::TelemetryRow;
    use common::config::{EstimatorConfig, MixtureFeature};

    #[test]
    fn one_feature_and_two_kinds_give_the_papers_analysis_exactly() {
        // Flat and rough robots whose sin θx wanders with the ground's std, 1 cm per tick.
        let mut rng = common::Rng::new(5);
        let mut rows = Vec::new();
        for env in 0..6u32 {
            let (area, sd) = if env < 3 {
                (AreaKind::Flat, 0.02)
            } else {
                (AreaKind::Rough, 0.07)
            };
            for tick in 0..400u64 {
                rows.push(TelemetryRow {
                    env,
                    tick,
                    area,
                    x: 0.01 * tick as f64,
                    sin_pitch: sd * rng.normal(),
                    ..TelemetryRow::default()
                });
            }
        }
        let series = split_series(&rows, 100);
        let cfg = EstimatorConfig::default();
        let paper_opts = crate::gmm::FitOptions::from_config(&cfg, 3);
        let opts = MixtureOptions::from_config(&cfg, 2, 3);
        let wheels = Wheels {
            radius: 0.035,
            dt: 0.1,
        };
        for window in [10, 20, 40, 70] {
            let paper = analyze_window(&series, window, &paper_opts, 0.002, MixtureFeature::Std)
                .expect("paper");
            let windows =
                window_features(&series, window, &[WindowFeature::PitchStd], 0.002, wheels)
                    .expect("features");
            let kinds = [AreaKind::Flat, AreaKind::Rough];
            let ours = fit_and_name(
                &windows,
                window,
                &[WindowFeature::PitchStd],
                &kinds,
                (&opts, KindsFit::Em),
                0.0,
            )
            .expect("kinds");
            assert_eq!(
                ours.accuracy.to_bits(),
                paper.accuracy.to_bits(),
                "w{window}"
            );
            assert_eq!(ours.component_kinds, kinds);
            let without_unknown: Vec<Vec<u64>> =
                ours.confusion.iter().map(|r| r[..2].to_vec()).collect();
            assert_eq!(without_unknown, paper.confusion, "w{window}");
            let Classifier::OneFeature(g) = &ours.model else {
                panic!("one feature fits the paper's mixture");
            };
            assert_eq!(g.means(), &paper.means[..]);
        }
    }

    #[test]
    fn the_assignment_is_the_best_one_to_one_not_the_greedy_one() {
        // Greedy would give component 0 kind 0 (9 windows), then component 1 kind 1 (1): 10
        // right. Swapping gives 8 + 8 = 16.
        let confusion = vec![vec![9, 8], vec![8, 1]];
        assert_eq!(assign(&confusion), vec![1, 0]);
        let by_kind = kind_confusion(&confusion, &[1, 0]);
        assert_eq!(by_kind, vec![vec![8, 9], vec![1, 8]]);
    }

    #[test]
    fn the_assignment_follows_any_permutation_of_the_components() {
        // Kind k's windows mostly in component perm[k].
        let base = [
            [90u64, 5, 3, 2],
            [4, 80, 10, 6],
            [1, 2, 95, 2],
            [3, 7, 5, 85],
        ];
        for perm in [[0, 1, 2, 3], [3, 2, 1, 0], [1, 3, 0, 2], [2, 0, 3, 1]] {
            let confusion: Vec<Vec<u64>> = base
                .iter()
                .map(|row| {
                    let mut out = vec![0; 4];
                    for (k, &count) in row.iter().enumerate() {
                        out[perm[k]] = count;
                    }
                    out
                })
                .collect();
            let kind_of = assign(&confusion);
            for (k, &c) in perm.iter().enumerate() {
                assert_eq!(kind_of[c], k, "perm {perm:?}: {kind_of:?}");
            }
        }
    }

    #[test]
    fn extra_components_join_their_majority_kind_and_macro_accuracy_weighs_kinds_alike() {
        // Three components for two kinds: component 2 is a second rough cluster.
        let confusion = vec![vec![100, 0, 10], vec![0, 50, 40]];
        let kind_of = assign(&confusion);
        assert_eq!(kind_of, vec![0, 1, 1]);
        let by_kind = kind_confusion(&confusion, &kind_of);
        assert_eq!(by_kind, vec![vec![100, 10], vec![0, 90]]);
        // Recalls 100/110 and 90/90: the mean, not the pooled 190/200.
        let m = macro_accuracy(&by_kind);
        assert!((m - 0.5 * (100.0 / 110.0 + 1.0)).abs() < 1e-12, "{m}");
    }

    #[test]
    fn a_labelled_fit_names_each_kind_after_its_own_component() {
        // Slope windows tilted and still, gravel ones level and shaking, flat ones neither.
        let mut rng = common::Rng::new(9);
        let mut windows = FeatureWindows {
            dim: 2,
            values: Vec::new(),
            kinds: Vec::new(),
            stationary: 0,
        };
        for (kind, tilt, shake) in [
            (AreaKind::Gravel, 0.0, 5.0),
            (AreaKind::Flat, 0.0, 0.0),
            (AreaKind::Slope, 5.0, 0.0),
        ] {
            for _ in 0..300 {
                windows
                    .values
                    .extend([tilt + rng.normal(), shake + rng.normal()]);
                windows.kinds.push(kind);
            }
        }
        let kinds = [AreaKind::Flat, AreaKind::Slope, AreaKind::Gravel];
        let features = [WindowFeature::MeanTilt, WindowFeature::PitchHighPass];
        let cfg = common::config::EstimatorConfig::default();
        let labelled = |components| {
            let opts = MixtureOptions::from_config(&cfg, components, 1);
            fit_and_name(
                &windows,
                30,
                &features,
                &kinds,
                (&opts, KindsFit::Labelled),
                0.0,
            )
        };
        let r = labelled(3).expect("labelled");
        assert!(r.macro_accuracy > 0.99, "{:?}", r.confusion);
        let mut named = r.component_kinds.clone();
        named.sort_by_key(|k| k.code());
        assert_eq!(
            named,
            vec![AreaKind::Flat, AreaKind::Slope, AreaKind::Gravel]
        );
        let err = labelled(2).expect_err("two components for three kinds");
        assert!(err.to_string().contains("one component per kind"), "{err}");
    }
}
