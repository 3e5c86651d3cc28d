//! A 1-D Gaussian mixture fitted by expectation–maximisation (SPEC S7 step 3).
//!
//! - Initialisation: k-means++ seeding (first centre uniform, each next one drawn with
//!   probability ∝ squared distance to the nearest chosen centre), then one hard assignment
//!   gives the initial weights, means and variances.
//! - Restarts: `restarts` independent seedings; the highest final log-likelihood wins.
//! - E-step in log space: `ln(w_k N(x; μ_k, σ_k²))` per component, normalised by
//!   log-sum-exp, so far-out points neither underflow every component nor produce NaN.
//! - M-step from sufficient statistics accumulated in the same pass, each taken about the
//!   component's previous mean (`Σ r (x − μ_old)`, `Σ r (x − μ_old)²`): no `n × K`
//!   responsibility matrix, and no catastrophic cancellation near convergence where the new
//!   mean is close to the old one.
//! - A variance floor keeps a component from collapsing onto one point (the likelihood is
//!   unbounded there). Flooring is the exact constrained maximiser in σ², so the
//!   log-likelihood still never decreases from one iteration to the next.
//! - Components are always stored in ascending order of mean: component 0 is "flat" (SPEC S7).

use crate::{EstimatorError, Result};
use common::config::EstimatorConfig;
use serde::{Deserialize, Serialize};

const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// How to fit: all from [`EstimatorConfig`] plus a seed.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Mixture components K (≥ 1; the config requires 2 ..= 16).
    pub components: usize,
    /// Independent k-means++ seedings; the best log-likelihood wins.
    pub restarts: usize,
    /// EM iteration cap per restart.
    pub max_iter: usize,
    /// Stop when the mean (per point) log-likelihood improves by less than this.
    pub tol: f64,
    /// Lower bound on each component's variance.
    pub var_floor: f64,
    /// Mixing weights held at 1/K (only means and variances are fitted).
    pub equal_weights: bool,
    /// Seed of the k-means++ draws (restart `r` uses stream `r`).
    pub seed: u64,
}

impl FitOptions {
    pub fn from_config(cfg: &EstimatorConfig, seed: u64) -> Self {
        Self {
            components: cfg.components,
            restarts: cfg.restarts,
            max_iter: cfg.max_iter,
            tol: cfg.tol,
            var_floor: cfg.var_floor,
            equal_weights: cfg.equal_weights,
            seed,
        }
    }
}

/// Mixture parameters, components sorted by ascending mean. Read back (`Deserialize`) through
/// [`Gmm::new`], so a stored model is validated and its caches rebuilt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "GmmParams")]
pub struct Gmm {
    weights: Vec<f64>,
    means: Vec<f64>,
    variances: Vec<f64>,
    /// `ln w_k`, cached for the per-tick path.
    #[serde(skip)]
    log_weight: Vec<f64>,
    /// `−½ ln(2π σ_k²)`, cached for the per-tick path.
    #[serde(skip)]
    log_scale: Vec<f64>,
    /// `1 / (2 σ_k²)`, cached for the per-tick path.
    #[serde(skip)]
    half_precision: Vec<f64>,
}

/// A stored [`Gmm`]'s parameters.
#[derive(Deserialize)]
struct GmmParams {
    weights: Vec<f64>,
    means: Vec<f64>,
    variances: Vec<f64>,
}

impl TryFrom<GmmParams> for Gmm {
    type Error = EstimatorError;

    fn try_from(p: GmmParams) -> Result<Self> {
        Self::new(p.weights, p.means, p.variances)
    }
}

/// The result of one E-step: the log-likelihood of the data under the current parameters and
/// the statistics the M-step needs.
#[derive(Debug, Clone, PartialEq)]
pub struct EStep {
    pub log_likelihood: f64,
    pub stats: SuffStats,
}

/// Per component k: `n[k] = Σ r_ik`, `s[k] = Σ r_ik (x_i − shift[k])`,
/// `q[k] = Σ r_ik (x_i − shift[k])²`, where `shift` is the component's mean when accumulated.
#[derive(Debug, Clone, PartialEq)]
pub struct SuffStats {
    pub n: Vec<f64>,
    pub s: Vec<f64>,
    pub q: Vec<f64>,
    pub shift: Vec<f64>,
}

/// The outcome of [`fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    pub model: Gmm,
    /// Total log-likelihood of the data under `model`.
    pub log_likelihood: f64,
    /// M-steps taken by the winning restart.
    pub iterations: usize,
    /// The winning restart stopped on the tolerance, not on the iteration cap.
    pub converged: bool,
    /// Log-likelihood before each M-step of the winning restart, and of the final model.
    pub history: Vec<f64>,
    /// Restarts that ended with a usable model (others lost a component).
    pub restarts_ok: usize,
}

impl Gmm {
    /// A mixture from its parameters, validated and sorted by mean. Weights must be positive
    /// and sum to 1 (within 1e-9); they are renormalised to absorb rounding.
    pub fn new(weights: Vec<f64>, means: Vec<f64>, variances: Vec<f64>) -> Result<Self> {
        let k = weights.len();
        let invalid = |reason: String| Err(EstimatorError::InvalidModel { reason });
        if k == 0 || means.len() != k || variances.len() != k {
            return invalid(format!(
                "needs equally many weights, means and variances (got {k}, {}, {})",
                means.len(),
                variances.len()
            ));
        }
        if weights
            .iter()
            .chain(&means)
            .chain(&variances)
            .any(|v| !v.is_finite())
        {
            return invalid("parameters must be finite".into());
        }
        if weights.iter().any(|&w| w <= 0.0) || variances.iter().any(|&v| v <= 0.0) {
            return invalid("weights and variances must be positive".into());
        }
        let total: f64 = weights.iter().sum();
        if (total - 1.0).abs() > 1e-9 {
            return invalid(format!("weights sum to {total}, not 1"));
        }
        // SPEC S7: the lowest-mean component is "flat", so components are kept sorted by mean.
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| means[a].total_cmp(&means[b]));
        let weights: Vec<f64> = order.iter().map(|&i| weights[i] / total).collect();
        let means: Vec<f64> = order.iter().map(|&i| means[i]).collect();
        let variances: Vec<f64> = order.iter().map(|&i| variances[i]).collect();
        let log_weight = weights.iter().map(|w| w.ln()).collect();
        let log_scale = variances.iter().map(|v| -0.5 * (LN_2PI + v.ln())).collect();
        let half_precision = variances.iter().map(|v| 0.5 / v).collect();
        Ok(Self {
            weights,
            means,
            variances,
            log_weight,
            log_scale,
            half_precision,
        })
    }

    pub fn components(&self) -> usize {
        self.weights.len()
    }

    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    pub fn means(&self) -> &[f64] {
        &self.means
    }

    pub fn variances(&self) -> &[f64] {
        &self.variances
    }

    pub fn stds(&self) -> Vec<f64> {
        self.variances.iter().map(|v| v.sqrt()).collect()
    }

    /// Writes `ln(w_k N(x; μ_k, σ_k²))` into `out` (length K) and returns `ln p(x)`.
    pub fn joint_log(&self, x: f64, out: &mut [f64]) -> f64 {
        self.joint_log_max(x, out);
        log_sum_exp(out)
    }

    /// Writes the posterior `P(k | x)` into `out` (length K) and returns `ln p(x)`.
    pub fn posteriors(&self, x: f64, out: &mut [f64]) -> f64 {
        let lse = self.joint_log(x, out);
        for o in out.iter_mut() {
            *o = (*o - lse).exp();
        }
        lse
    }

    /// `ln w_k` of every component (the HMM removes them to get emission densities).
    pub fn log_weights(&self) -> &[f64] {
        &self.log_weight
    }

    /// The most probable component for `x` (maximum posterior).
    pub fn classify(&self, x: f64) -> usize {
        let mut best = (0, f64::NEG_INFINITY);
        for k in 0..self.components() {
            let l = self.joint_log_at(x, k);
            if l > best.1 {
                best = (k, l);
            }
        }
        best.0
    }

    /// Total log-likelihood `Σ ln p(x_i)`.
    pub fn log_likelihood(&self, data: &[f64]) -> f64 {
        let mut scratch = vec![0.0; self.components()];
        data.iter().map(|&x| self.joint_log(x, &mut scratch)).sum()
    }

    /// The E-step: responsibilities of every point, folded into sufficient statistics.
    pub fn e_step(&self, data: &[f64]) -> EStep {
        let k = self.components();
        let mut stats = SuffStats {
            n: vec![0.0; k],
            s: vec![0.0; k],
            q: vec![0.0; k],
            shift: self.means.clone(),
        };
        let mut l = vec![0.0; k];
        let mut log_likelihood = 0.0;
        for &x in data {
            let m = self.joint_log_max(x, &mut l);
            let mut total = 0.0;
            for v in &mut l {
                *v = (*v - m).exp();
                total += *v;
            }
            log_likelihood += m + total.ln();
            for (c, &weight) in l.iter().enumerate() {
                let r = weight / total;
                let d = x - stats.shift[c];
                stats.n[c] += r;
                stats.s[c] += r * d;
                stats.q[c] += r * d * d;
            }
        }
        EStep {
            log_likelihood,
            stats,
        }
    }

    /// The M-step: maximum-likelihood parameters given the E-step's statistics, each variance
    /// raised to `var_floor`, the weights 1/K when `equal_weights` (the constrained maximiser,
    /// so EM still never lowers the likelihood). Fails if a component has (numerically) no
    /// responsibility left.
    pub fn m_step(stats: &SuffStats, var_floor: f64, equal_weights: bool) -> Result<Self> {
        let total: f64 = stats.n.iter().sum();
        let mut weights = Vec::with_capacity(stats.n.len());
        let mut means = Vec::with_capacity(stats.n.len());
        let mut variances = Vec::with_capacity(stats.n.len());
        for c in 0..stats.n.len() {
            let n = stats.n[c];
            if n.is_nan() || n <= f64::EPSILON * total {
                return Err(EstimatorError::InvalidModel {
                    reason: format!("component {c} lost all its points (responsibility {n:e})"),
                });
            }
            let ds = stats.s[c] / n;
            weights.push(if equal_weights {
                1.0 / stats.n.len() as f64
            } else {
                n / total
            });
            means.push(stats.shift[c] + ds);
            variances.push((stats.q[c] / n - ds * ds).max(var_floor));
        }
        Self::new(weights, means, variances)
    }

    /// `ln(w_k N(x))` into `out`; returns the largest (the log-sum-exp pivot).
    fn joint_log_max(&self, x: f64, out: &mut [f64]) -> f64 {
        let mut m = f64::NEG_INFINITY;
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.joint_log_at(x, k);
            m = m.max(*o);
        }
        m
    }

    #[inline]
    fn joint_log_at(&self, x: f64, k: usize) -> f64 {
        let d = x - self.means[k];
        self.log_weight[k] + self.log_scale[k] - d * d * self.half_precision[k]
    }
}

/// `ln Σ exp(v)`, pivoted on the maximum so it neither overflows nor underflows.
pub fn log_sum_exp(v: &[f64]) -> f64 {
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + v.iter().map(|x| (x - m).exp()).sum::<f64>().ln()
}

/// Fits a K-component mixture to `data`: `restarts` k-means++ seedings, the best
/// log-likelihood wins. Errors on non-finite data, fewer points or distinct values than
/// components, or when every restart lost a component.
pub fn fit(data: &[f64], opts: &FitOptions) -> Result<FitReport> {
    check_data(data, opts.components)?;
    let spread = variance(data);
    let (mut report, ok) = best_of_restarts(
        opts.restarts,
        opts.seed,
        |rng| {
            kmeans_pp(data, opts.components, spread, opts.var_floor, rng)
                .and_then(|init| run_em(data, init, opts))
        },
        |r| r.log_likelihood,
    )?;
    report.restarts_ok = ok;
    Ok(report)
}

/// Runs `attempt` once per restart (at least one), restart r with stream r of `seed`; the
/// outcome of the highest `log_likelihood` wins (the earliest among equals), returned with
/// how many restarts succeeded. Fails with the last failure's reason when none did.
pub fn best_of_restarts<T>(
    restarts: usize,
    seed: u64,
    mut attempt: impl FnMut(&mut common::Rng) -> Result<T>,
    log_likelihood: impl Fn(&T) -> f64,
) -> Result<(T, usize)> {
    let mut best: Option<T> = None;
    let (mut ok, mut last_error) = (0, None);
    for restart in 0..restarts.max(1) {
        let mut rng = common::Rng::derive(seed, restart as u64);
        match attempt(&mut rng) {
            Ok(outcome) => {
                ok += 1;
                if best
                    .as_ref()
                    .is_none_or(|b| log_likelihood(&outcome) > log_likelihood(b))
                {
                    best = Some(outcome);
                }
            }
            Err(e) => last_error = Some(e),
        }
    }
    best.map(|b| (b, ok)).ok_or_else(|| EstimatorError::NoFit {
        restarts: restarts.max(1),
        reason: last_error.map_or_else(|| "no restart ran".into(), |e| e.to_string()),
    })
}

/// One EM run started from `start` (a warm start, e.g. the previous model of the online
/// estimator): no random seeding, so components keep their identity.
pub fn fit_from(data: &[f64], start: &Gmm, opts: &FitOptions) -> Result<FitReport> {
    check_data(data, start.components())?;
    run_em(data, start.clone(), opts).map_err(|e| EstimatorError::NoFit {
        restarts: 1,
        reason: e.to_string(),
    })
}

fn check_data(data: &[f64], components: usize) -> Result<()> {
    if let Some((index, &value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(EstimatorError::NonFinite { index, value });
    }
    if components == 0 || data.len() < components {
        return Err(EstimatorError::TooFewPoints {
            n: data.len(),
            components,
        });
    }
    let mut distinct: Vec<f64> = Vec::with_capacity(components);
    for &x in data {
        if !distinct.contains(&x) {
            distinct.push(x);
            if distinct.len() == components {
                return Ok(());
            }
        }
    }
    Err(EstimatorError::Degenerate {
        distinct: distinct.len(),
        components,
    })
}

fn variance(data: &[f64]) -> f64 {
    let n = data.len() as f64;
    let mean = data.iter().sum::<f64>() / n;
    data.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n
}

/// k-means++'s next centre: point i drawn with probability ∝ `d2[i]`, its squared distance
/// to the nearest centre so far (some `d2` must be positive).
pub fn draw_by_distance(d2: &[f64], rng: &mut common::Rng) -> usize {
    let total: f64 = d2.iter().sum();
    let target = rng.uniform() * total;
    let mut acc = 0.0;
    for (i, &d) in d2.iter().enumerate() {
        acc += d;
        if acc > target && d > 0.0 {
            return i;
        }
    }
    d2.iter().rposition(|&d| d > 0.0).unwrap_or(0)
}

/// k-means++ seeding followed by one hard assignment to the nearest centre.
fn kmeans_pp(
    data: &[f64],
    k: usize,
    spread: f64,
    var_floor: f64,
    rng: &mut common::Rng,
) -> Result<Gmm> {
    let mut centres = vec![data[rng.below(data.len())]];
    let mut d2: Vec<f64> = data.iter().map(|x| (x - centres[0]).powi(2)).collect();
    while centres.len() < k {
        // check_data guarantees k distinct values, so some point is off every centre.
        let c = data[draw_by_distance(&d2, rng)];
        centres.push(c);
        for (d, x) in d2.iter_mut().zip(data) {
            *d = d.min((x - c).powi(2));
        }
    }
    // One Lloyd assignment, statistics taken about each centre (see the module docs).
    let (mut count, mut s, mut q) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    for &x in data {
        let nearest = (0..k)
            .min_by(|&a, &b| (x - centres[a]).abs().total_cmp(&(x - centres[b]).abs()))
            .unwrap_or(0);
        let d = x - centres[nearest];
        count[nearest] += 1.0;
        s[nearest] += d;
        q[nearest] += d * d;
    }
    let n = data.len() as f64;
    let mut weights = Vec::with_capacity(k);
    let mut means = Vec::with_capacity(k);
    let mut variances = Vec::with_capacity(k);
    for c in 0..k {
        let ds = s[c] / count[c];
        let var = q[c] / count[c] - ds * ds;
        weights.push(count[c] / n);
        means.push(centres[c] + ds);
        // A singleton cluster has no spread of its own: start it as wide as the data.
        variances.push(
            if count[c] >= 2.0 && var > 0.0 {
                var
            } else {
                spread
            }
            .max(var_floor),
        );
    }
    Gmm::new(weights, means, variances)
}

/// EM iterations from `model` until the mean log-likelihood gain drops below `tol` or
/// `max_iter` M-steps are done.
fn run_em(data: &[f64], mut model: Gmm, opts: &FitOptions) -> Result<FitReport> {
    let n = data.len() as f64;
    if opts.equal_weights {
        let k = model.components();
        model = Gmm::new(vec![1.0 / k as f64; k], model.means, model.variances)?;
    }
    let mut history: Vec<f64> = Vec::new();
    let mut converged = false;
    let mut iterations = 0;
    loop {
        let e = model.e_step(data);
        if !e.log_likelihood.is_finite() {
            return Err(EstimatorError::InvalidModel {
                reason: format!("log-likelihood became {}", e.log_likelihood),
            });
        }
        if let Some(&prev) = history.last() {
            converged = (e.log_likelihood - prev) / n < opts.tol;
        }
        history.push(e.log_likelihood);
        if converged || iterations == opts.max_iter {
            break;
        }
        model = Gmm::m_step(&e.stats, opts.var_floor, opts.equal_weights)?;
        iterations += 1;
    }
    let log_likelihood = history.last().copied().unwrap_or(f64::NEG_INFINITY);
    Ok(FitReport {
        model,
        log_likelihood,
        iterations,
        converged,
        history,
        restarts_ok: 1,
    })
}

#[cfg(test)]
mod tests;
