//! A d-dimensional Gaussian mixture fitted by expectation–maximisation, for windows described
//! by several features (beyond SPEC S7's one; its one-feature fit is [`crate::gmm`]).
//!
//! - Features are standardised first (each to mean 0 and std 1 over the fitted data) and the
//!   model keeps that transform, so features of any units weigh alike in the k-means++ seeding
//!   and one variance floor suits them all.
//! - Covariance `full` or `diagonal`. A full covariance gets `var_floor` added to its diagonal
//!   (it stays positive definite even for perfectly correlated features); a diagonal one has
//!   each variance raised to it.
//! - Densities go through each covariance's Cholesky factor, and the E-step works in log space
//!   (log-sum-exp), so far-out points neither underflow nor produce NaN.
//! - Seeding, restarts, tolerance, iteration cap and equal weights as [`crate::gmm`]'s.
//! - Components are stored in ascending order of their mean's first feature, so a fit is one
//!   canonical model whatever the seeding's order; which terrain each stands for is named by
//!   [`crate::kinds::assign`], not by that order.

use crate::gmm::FitOptions;
use crate::{EstimatorError, Result};
pub use common::config::Covariance;
use common::config::EstimatorConfig;
use serde::{Deserialize, Serialize};

const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// How to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct MixtureOptions {
    /// Components, restarts, iteration cap, tolerance, equal weights and seed, as SPEC S7's
    /// fit; the variance floor is in standardised units here.
    pub em: FitOptions,
    pub covariance: Covariance,
}

impl MixtureOptions {
    /// `cfg`'s covariance and EM settings for `components` components and `seed`.
    pub fn from_config(cfg: &EstimatorConfig, components: usize, seed: u64) -> Self {
        Self {
            em: FitOptions {
                components,
                ..FitOptions::from_config(cfg, seed)
            },
            covariance: cfg.covariance,
        }
    }
}

/// A mixture's parameters, as `kinds.json` stores them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MixtureParams {
    /// Per feature: the data's mean and std the model standardises with.
    pub centre: Vec<f64>,
    pub scale: Vec<f64>,
    pub covariance: Covariance,
    pub weights: Vec<f64>,
    /// Per component, in standardised units: the mean (d) and the covariance (d × d, row-major).
    pub means: Vec<Vec<f64>>,
    pub covs: Vec<Vec<f64>>,
}

/// A fitted mixture over `dim` features: its parameters (which it derefs to) and each
/// covariance's Cholesky factor. Stored as the parameters and read back through
/// [`Mixture::new`], so a stored model is validated and its factors rebuilt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "MixtureParams", try_from = "MixtureParams")]
pub struct Mixture {
    params: MixtureParams,
    dim: usize,
    /// Per component: the covariance's lower Cholesky factor (row-major) and
    /// `ln w − ½ (d ln 2π + ln |Σ|)`.
    chol: Vec<Vec<f64>>,
    log_norm: Vec<f64>,
}

impl std::ops::Deref for Mixture {
    type Target = MixtureParams;

    fn deref(&self) -> &MixtureParams {
        &self.params
    }
}

impl From<Mixture> for MixtureParams {
    fn from(m: Mixture) -> Self {
        m.params
    }
}

impl TryFrom<MixtureParams> for Mixture {
    type Error = EstimatorError;

    fn try_from(p: MixtureParams) -> Result<Self> {
        Self::new(p.centre, p.scale, p.covariance, p.weights, p.means, p.covs)
    }
}

/// The outcome of [`fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct MixtureFit {
    pub model: Mixture,
    /// Of the standardised data (the raw data's differs by a constant, `−n Σ ln scale`).
    pub log_likelihood: f64,
    pub iterations: usize,
    pub converged: bool,
    /// Restarts that ended with a usable model.
    pub restarts_ok: usize,
}

impl Mixture {
    /// A mixture from its parameters (standardised units), validated, its Cholesky factors
    /// computed and its components sorted by their mean's first feature.
    pub fn new(
        centre: Vec<f64>,
        scale: Vec<f64>,
        covariance: Covariance,
        weights: Vec<f64>,
        means: Vec<Vec<f64>>,
        covs: Vec<Vec<f64>>,
    ) -> Result<Self> {
        let invalid = |reason: String| EstimatorError::InvalidModel { reason };
        let (k, d) = (weights.len(), centre.len());
        if k == 0 || d == 0 || d > 16 || scale.len() != d || means.len() != k || covs.len() != k {
            return Err(invalid(format!(
                "needs K ≥ 1 components and 1 ..= 16 features with matching shapes (K = {k}, d = {d})"
            )));
        }
        if means.iter().any(|m| m.len() != d) || covs.iter().any(|c| c.len() != d * d) {
            return Err(invalid(format!(
                "means must have {d} and covariances {} entries",
                d * d
            )));
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(&centre) && finite(&scale) && finite(&weights))
            || means.iter().chain(&covs).any(|v| !finite(v))
        {
            return Err(invalid("parameters must be finite".into()));
        }
        if weights.iter().any(|&w| w <= 0.0) || scale.iter().any(|&s| s <= 0.0) {
            return Err(invalid("weights and scales must be positive".into()));
        }
        let total: f64 = weights.iter().sum();
        if (total - 1.0).abs() > 1e-9 {
            return Err(invalid(format!("weights sum to {total}, not 1")));
        }
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| means[a][0].total_cmp(&means[b][0]));
        let weights: Vec<f64> = order.iter().map(|&i| weights[i] / total).collect();
        let means: Vec<Vec<f64>> = order.iter().map(|&i| means[i].clone()).collect();
        let covs: Vec<Vec<f64>> = order.iter().map(|&i| covs[i].clone()).collect();
        let mut chol = Vec::with_capacity(k);
        let mut log_norm = Vec::with_capacity(k);
        for (c, (cov, w)) in covs.iter().zip(&weights).enumerate() {
            let l = cholesky(cov, d).ok_or_else(|| {
                invalid(format!(
                    "component {c}'s covariance is not positive definite"
                ))
            })?;
            let log_det: f64 = (0..d).map(|i| 2.0 * l[i * d + i].ln()).sum();
            log_norm.push(w.ln() - 0.5 * (d as f64 * LN_2PI + log_det));
            chol.push(l);
        }
        Ok(Self {
            params: MixtureParams {
                centre,
                scale,
                covariance,
                weights,
                means,
                covs,
            },
            dim: d,
            chol,
            log_norm,
        })
    }

    pub fn components(&self) -> usize {
        self.weights.len()
    }

    /// `x` (raw feature values) in the model's standardised units.
    pub fn standardise(&self, x: &[f64], out: &mut [f64]) {
        for ((o, v), (c, s)) in out
            .iter_mut()
            .zip(x)
            .zip(self.centre.iter().zip(&self.scale))
        {
            *o = (v - c) / s;
        }
    }

    /// Component `c`'s squared Mahalanobis distance to a standardised point `z`.
    pub fn mahalanobis2(&self, z: &[f64], c: usize) -> f64 {
        let (d, l, m) = (self.dim, &self.chol[c], &self.means[c]);
        // Forward substitution: L y = z − μ, and the distance is |y|².
        let mut y = [0.0f64; 16];
        let mut sum = 0.0;
        for i in 0..d {
            let mut v = z[i] - m[i];
            for j in 0..i {
                v -= l[i * d + j] * y[j];
            }
            y[i] = v / l[i * d + i];
            sum += y[i] * y[i];
        }
        sum
    }

    /// Writes `ln(w_c N(z; μ_c, Σ_c))` of a standardised point into `out` (length K) and
    /// returns `ln p(z)`.
    pub fn joint_log(&self, z: &[f64], out: &mut [f64]) -> f64 {
        for (c, o) in out.iter_mut().enumerate() {
            *o = self.log_norm[c] - 0.5 * self.mahalanobis2(z, c);
        }
        crate::gmm::log_sum_exp(out)
    }

    /// The most probable component for raw feature values `x`.
    pub fn classify(&self, x: &[f64]) -> usize {
        let mut z = vec![0.0; self.dim];
        self.standardise(x, &mut z);
        let mut l = vec![0.0; self.components()];
        self.joint_log(&z, &mut l);
        argmax(&l)
    }

    /// The most probable component for `x`, or `None` when no component explains it: the
    /// nearest is farther than `beyond` standard deviations (Mahalanobis; 0 never refuses).
    pub fn classify_or_unknown(&self, x: &[f64], beyond: f64) -> Option<usize> {
        let mut z = vec![0.0; self.dim];
        self.standardise(x, &mut z);
        if beyond > 0.0 {
            let nearest = (0..self.components())
                .map(|c| self.mahalanobis2(&z, c))
                .fold(f64::INFINITY, f64::min);
            if nearest > beyond * beyond {
                return None;
            }
        }
        let mut l = vec![0.0; self.components()];
        self.joint_log(&z, &mut l);
        Some(argmax(&l))
    }
}

fn argmax(v: &[f64]) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (i, &x) in v.iter().enumerate() {
        if x > best.1 {
            best = (i, x);
        }
    }
    best.0
}

/// The lower Cholesky factor of the symmetric `d × d` matrix `a` (row-major), or `None` if it
/// is not positive definite.
fn cholesky(a: &[f64], d: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i * d + k] * l[j * d + k]).sum();
            if i == j {
                let v = a[i * d + i] - s;
                if !(v > 0.0 && v.is_finite()) {
                    return None;
                }
                l[i * d + i] = v.sqrt();
            } else {
                l[i * d + j] = (a[i * d + j] - s) / l[j * d + j];
            }
        }
    }
    Some(l)
}

/// Fits a K-component mixture to `data`, `n` points of `dim` features each, row-major.
/// Errors on non-finite data, more than 16 features, fewer points than components, a
/// constant feature, or when every restart lost a component.
pub fn fit(data: &[f64], dim: usize, opts: &MixtureOptions) -> Result<MixtureFit> {
    let (z, centre, scale) = standardised(data, dim, opts.em.components)?;
    let (mut fit, ok) = crate::gmm::best_of_restarts(
        opts.em.restarts,
        opts.em.seed,
        |rng| {
            seed_components(&z, dim, opts, rng)
                .and_then(|m| run_em(&z, dim, m, opts, (&centre, &scale)))
        },
        |f| f.log_likelihood,
    )?;
    fit.restarts_ok = ok;
    Ok(fit)
}

/// The mixture whose component `c` is the Gaussian of the points labelled `c` (`labels`, one
/// per point, each below `opts`' components): one M-step on the labels, no EM
/// (`estimator.kinds-fit = "labelled"`). Components are stored sorted as every mixture's, so
/// which component is which label is for [`crate::kinds::assign`] to name. Errors as
/// [`fit`], and on a label out of range or one without points.
pub fn fit_labelled(
    data: &[f64],
    dim: usize,
    labels: &[usize],
    opts: &MixtureOptions,
) -> Result<MixtureFit> {
    let k = opts.em.components;
    let (z, centre, scale) = standardised(data, dim, k)?;
    let n = z.len() / dim;
    if labels.len() != n {
        return Err(EstimatorError::InvalidModel {
            reason: format!("{} labels for {n} points", labels.len()),
        });
    }
    let mut resp = vec![0.0; n * k];
    for (i, &label) in labels.iter().enumerate() {
        if label >= k {
            return Err(EstimatorError::InvalidModel {
                reason: format!("label {label} of point {i} is not one of {k} components"),
            });
        }
        resp[i * k + label] = 1.0;
    }
    let p = m_step(&z, dim, &resp, opts)?.params;
    let model = Mixture::new(centre, scale, p.covariance, p.weights, p.means, p.covs)?;
    let mut joint = vec![0.0; k];
    let log_likelihood = z
        .chunks_exact(dim)
        .map(|x| model.joint_log(x, &mut joint))
        .sum();
    Ok(MixtureFit {
        model,
        log_likelihood,
        iterations: 0,
        converged: true,
        restarts_ok: 1,
    })
}

/// `data` checked and standardised, with the centre and scale it was standardised by.
fn standardised(
    data: &[f64],
    dim: usize,
    components: usize,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    if dim == 0 || dim > 16 || !data.len().is_multiple_of(dim) {
        return Err(EstimatorError::InvalidModel {
            reason: format!(
                "{} values do not make points of 1 ..= 16 features (d = {dim})",
                data.len()
            ),
        });
    }
    if let Some((index, &value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(EstimatorError::NonFinite { index, value });
    }
    let n = data.len() / dim;
    if n < components.max(2) {
        return Err(EstimatorError::TooFewPoints { n, components });
    }
    let (centre, scale) = standardisation(data, dim)?;
    let z: Vec<f64> = data
        .chunks_exact(dim)
        .flat_map(|p| {
            (0..dim)
                .map(|i| (p[i] - centre[i]) / scale[i])
                .collect::<Vec<_>>()
        })
        .collect();
    Ok((z, centre, scale))
}

/// Each feature's mean and (population) std; a constant feature cannot be standardised.
fn standardisation(data: &[f64], dim: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = (data.len() / dim) as f64;
    let mut centre = vec![0.0; dim];
    for p in data.chunks_exact(dim) {
        for (c, v) in centre.iter_mut().zip(p) {
            *c += v / n;
        }
    }
    let mut scale = vec![0.0; dim];
    for p in data.chunks_exact(dim) {
        for i in 0..dim {
            scale[i] += (p[i] - centre[i]).powi(2) / n;
        }
    }
    for (i, s) in scale.iter_mut().enumerate() {
        *s = s.sqrt();
        if s.is_nan() || *s <= 0.0 {
            return Err(EstimatorError::Degenerate {
                distinct: 1,
                components: i + 1,
            });
        }
    }
    Ok((centre, scale))
}

/// k-means++ centres (squared Euclidean distance in standardised units), then one hard
/// assignment gives each component its weight, mean and covariance.
fn seed_components(
    z: &[f64],
    dim: usize,
    opts: &MixtureOptions,
    rng: &mut common::Rng,
) -> Result<Mixture> {
    let n = z.len() / dim;
    let k = opts.em.components;
    let point = |i: usize| &z[i * dim..(i + 1) * dim];
    let dist2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
    let mut centres = vec![point(rng.below(n)).to_vec()];
    let mut d2: Vec<f64> = (0..n).map(|i| dist2(point(i), &centres[0])).collect();
    while centres.len() < k {
        let total: f64 = d2.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return Err(EstimatorError::Degenerate {
                distinct: centres.len(),
                components: k,
            });
        }
        let c = point(crate::gmm::draw_by_distance(&d2, rng)).to_vec();
        for (i, d) in d2.iter_mut().enumerate() {
            *d = d.min(dist2(point(i), &c));
        }
        centres.push(c);
    }
    let mut resp = vec![0.0; n * k];
    for i in 0..n {
        let nearest = (0..k)
            .min_by(|&a, &b| dist2(point(i), &centres[a]).total_cmp(&dist2(point(i), &centres[b])))
            .unwrap_or(0);
        resp[i * k + nearest] = 1.0;
    }
    m_step(z, dim, &resp, opts)
}

/// The M-step from responsibilities `resp` (n × K): weights, means and floored covariances,
/// over standardised data (the model's own standardisation is the identity until [`run_em`]
/// gives it the data's).
fn m_step(z: &[f64], dim: usize, resp: &[f64], opts: &MixtureOptions) -> Result<Mixture> {
    let k = opts.em.components;
    let n = z.len() / dim;
    let mut weights = vec![0.0; k];
    let mut means = vec![vec![0.0; dim]; k];
    for i in 0..n {
        for c in 0..k {
            let r = resp[i * k + c];
            weights[c] += r;
            for f in 0..dim {
                means[c][f] += r * z[i * dim + f];
            }
        }
    }
    for c in 0..k {
        if weights[c].is_nan() || weights[c] <= f64::EPSILON * n as f64 {
            return Err(EstimatorError::InvalidModel {
                reason: format!(
                    "component {c} lost all its points (responsibility {:e})",
                    weights[c]
                ),
            });
        }
        for m in &mut means[c] {
            *m /= weights[c];
        }
    }
    let mut covs = vec![vec![0.0; dim * dim]; k];
    for i in 0..n {
        let p = &z[i * dim..(i + 1) * dim];
        for c in 0..k {
            let r = resp[i * k + c];
            for a in 0..dim {
                let da = p[a] - means[c][a];
                for b in 0..=a {
                    covs[c][a * dim + b] += r * da * (p[b] - means[c][b]);
                }
            }
        }
    }
    for c in 0..k {
        for a in 0..dim {
            for b in 0..=a {
                let v = covs[c][a * dim + b] / weights[c];
                let v = match (opts.covariance, a == b) {
                    (Covariance::Full, true) => v + opts.em.var_floor,
                    (Covariance::Diagonal, true) => v.max(opts.em.var_floor),
                    (Covariance::Full, false) => v,
                    (Covariance::Diagonal, false) => 0.0,
                };
                covs[c][a * dim + b] = v;
                covs[c][b * dim + a] = v;
            }
        }
    }
    let weights = if opts.em.equal_weights {
        vec![1.0 / k as f64; k]
    } else {
        weights.iter().map(|w| w / n as f64).collect()
    };
    Mixture::new(
        vec![0.0; dim],
        vec![1.0; dim],
        opts.covariance,
        weights,
        means,
        covs,
    )
}

/// EM from `model` until the mean log-likelihood gain drops below `tol` or `max_iter`
/// M-steps are done; the result carries the standardisation `standard`.
fn run_em(
    z: &[f64],
    dim: usize,
    mut model: Mixture,
    opts: &MixtureOptions,
    standard: (&[f64], &[f64]),
) -> Result<MixtureFit> {
    let (n, k) = (z.len() / dim, opts.em.components);
    let mut resp = vec![0.0; n * k];
    let mut previous: Option<f64> = None;
    let (mut iterations, mut converged) = (0, false);
    loop {
        let mut ll = 0.0;
        for i in 0..n {
            let row = &mut resp[i * k..(i + 1) * k];
            let lse = model.joint_log(&z[i * dim..(i + 1) * dim], row);
            ll += lse;
            for r in row.iter_mut() {
                *r = (*r - lse).exp();
            }
        }
        if !ll.is_finite() {
            return Err(EstimatorError::InvalidModel {
                reason: format!("log-likelihood became {ll}"),
            });
        }
        if let Some(p) = previous {
            converged = (ll - p) / (n as f64) < opts.em.tol;
        }
        previous = Some(ll);
        if converged || iterations == opts.em.max_iter {
            break;
        }
        model = m_step(z, dim, &resp, opts)?;
        iterations += 1;
    }
    let p = model.params;
    let model = Mixture::new(
        standard.0.to_vec(),
        standard.1.to_vec(),
        p.covariance,
        p.weights,
        p.means,
        p.covs,
    )?;
    Ok(MixtureFit {
        model,
        log_likelihood: previous.unwrap_or(f64::NEG_INFINITY),
        iterations,
        converged,
        restarts_ok: 1,
    })
}

#[cfg(test)]
mod tests;
