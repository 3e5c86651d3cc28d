//! Online terrain estimation: what the runtime calls once per env and tick.
//!
//! Per env: the rolling std of sin θx over the last `online-window` ticks (sample std,
//! [`Ddof::Sample`]). Every full-window value also goes into a pool shared by all envs (the
//! newest `pool-size` values); the mixture is first fitted once the pool holds
//! [`MIN_POINTS_PER_COMPONENT`] values per component, then refitted on the pool every
//! `refit-every` ticks (a tick = one observation of every env).
//!
//! Label stability: components are always ordered by ascending mean (0 = flat, SPEC S7), and a
//! refit is a warm start from the previous model, so each component continues as itself. In
//! one dimension the order-preserving pairing of old and new components is also the one that
//! minimises the total shift of their means, so "sort by mean" *is* the matching to the
//! previous components; the HMM belief of every env is carried over under it. A refit that
//! fails (e.g. a constant pool) keeps the previous model and is counted in [`OnlineStats`].
//! Caveat: the first fit defines the classes, so the pool should see every terrain before it
//! (or start from an offline model with [`OnlineEstimator::with_model`]).
//!
//! Optional K-state HMM forward filter (`stay-prob` > 0): the terrain persists from one tick
//! to the next with probability `stay-prob` and otherwise moves to any other class uniformly;
//! the emission is the component density of the window std, raised to the power `1/w`.
//! Consecutive windows share `w − 1` of their `w` samples, so each sample would otherwise be
//! counted as evidence `w` times and the filter would just echo the raw classifier's runs of
//! errors; tempered, it accumulates roughly one window's worth of independent evidence. It
//! trades a few ticks of detection delay for far fewer misclassifications at short windows.
//! `stay-prob = 0` reports the raw posterior.
//!
//! Stationary windows ([`OnlineEstimator::gate_stationary`], `estimator.min-speed`): when the
//! robot's path over the window is shorter than the gate, the window std is neither pooled nor
//! classified, and the env keeps its last estimate. A robot wedged on a rough bump holds its
//! pitch still; without the gate it reads as flat ground, and a cluster of such windows can
//! take over a mixture component.

use crate::gmm::{self, FitOptions, Gmm};
use crate::rolling::{Ddof, RollingPath, RollingStd};
use crate::{EstimatorError, Result};
use common::config::{EstimatorConfig, MixtureFeature};

/// Pool values per mixture component before the first fit.
pub const MIN_POINTS_PER_COMPONENT: usize = 50;

/// The estimate for one env after one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Terrain class: mixture component, 0 = lowest mean = flat; HMM-filtered when the filter
    /// is on. `None` until the window is full and a mixture has been fitted.
    pub class: Option<usize>,
    /// Probability of `class` (filtered belief or raw posterior); 0 when `class` is `None`.
    pub posterior: f64,
    /// The raw mixture classification (maximum posterior, no filter).
    pub raw_class: Option<usize>,
    /// Sample std of sin θx over the window, once full.
    pub window_std: Option<f64>,
    /// Window size, ticks.
    pub window: usize,
}

/// Counters for monitoring.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OnlineStats {
    pub observations: u64,
    pub fits: u64,
    pub failed_fits: u64,
    /// Full windows left out as stationary.
    pub stationary: u64,
}

#[derive(Debug, Clone)]
struct EnvState {
    rolling: RollingStd,
    travel: RollingPath,
    /// HMM belief over classes; empty until the env's first classified tick.
    belief: Vec<f64>,
    /// The last class and its probability, kept through stationary windows.
    held: Option<(usize, f64)>,
}

/// The newest `cap` window-std values of all envs (a ring; order is irrelevant to EM).
#[derive(Debug, Clone)]
struct Pool {
    values: Vec<f64>,
    cap: usize,
    next: usize,
}

impl Pool {
    fn push(&mut self, x: f64) {
        if self.values.len() < self.cap {
            self.values.push(x);
        } else {
            self.values[self.next] = x;
            self.next = (self.next + 1) % self.cap;
        }
    }
}

/// Per-env online terrain classifier with a periodically refitted mixture.
#[derive(Debug, Clone)]
pub struct OnlineEstimator {
    opts: FitOptions,
    window: usize,
    /// Observations between refits: `refit-every` ticks × envs; `u64::MAX` (never) for 0.
    refit_interval: u64,
    min_first_fit: usize,
    stay_prob: f64,
    /// What the mixture sees of each window's std (`estimator.feature`).
    feature: MixtureFeature,
    /// Path over a window below which it is stationary, metres; 0: no gate.
    min_travel: f64,
    envs: Vec<EnvState>,
    pool: Pool,
    model: Option<Gmm>,
    next_fit_at: u64,
    stats: OnlineStats,
    scratch: Vec<f64>,
}

impl OnlineEstimator {
    /// An estimator for `num_envs` envs with no mixture yet. `seed` drives the first fit's
    /// k-means++ seeding. The config is assumed validated ([`common::Config::validate`]).
    pub fn new(cfg: &EstimatorConfig, num_envs: usize, seed: u64) -> Result<Self> {
        if num_envs == 0 {
            return Err(EstimatorError::NoEnvs);
        }
        let rolling = RollingStd::new(cfg.online_window, Ddof::Sample)?;
        let k = cfg.components.max(1);
        Ok(Self {
            opts: FitOptions::from_config(cfg, seed),
            window: cfg.online_window,
            refit_interval: match cfg.refit_every {
                0 => u64::MAX,
                ticks => (ticks * num_envs) as u64,
            },
            min_first_fit: (MIN_POINTS_PER_COMPONENT * k).min(cfg.pool_size.max(k)),
            stay_prob: cfg.stay_prob,
            feature: cfg.feature,
            min_travel: 0.0,
            envs: vec![
                EnvState {
                    rolling,
                    travel: RollingPath::new(cfg.online_window)?,
                    belief: Vec::with_capacity(k),
                    held: None,
                };
                num_envs
            ],
            pool: Pool {
                values: Vec::with_capacity(cfg.pool_size.min(1 << 20)),
                cap: cfg.pool_size.max(1),
                next: 0,
            },
            model: None,
            next_fit_at: 0,
            stats: OnlineStats::default(),
            scratch: vec![0.0; k],
        })
    }

    /// As [`new`](Self::new), but classifying from the first full window with `model` (e.g.
    /// from an offline analysis); refits warm-start from it.
    pub fn with_model(
        cfg: &EstimatorConfig,
        num_envs: usize,
        seed: u64,
        model: Gmm,
    ) -> Result<Self> {
        let mut est = Self::new(cfg, num_envs, seed)?;
        est.scratch = vec![0.0; model.components()];
        est.opts.components = model.components();
        est.model = Some(model);
        est.next_fit_at = est.refit_interval;
        Ok(est)
    }

    /// [`with_model`](Self::with_model) with the offline fit `estimator.model` names (SPEC S7),
    /// else [`new`](Self::new).
    pub fn from_config(cfg: &EstimatorConfig, num_envs: usize, seed: u64) -> Result<Self> {
        match cfg.offline_mixture()? {
            None => Self::new(cfg, num_envs, seed),
            Some(m) => {
                let variances = m.stds.iter().map(|s| s * s).collect();
                let model = Gmm::new(m.weights, m.means, variances)?;
                Self::with_model(cfg, num_envs, seed, model)
            }
        }
    }

    /// Leaves out windows whose path is shorter than `min_step_travel` (metres per tick,
    /// [`common::Config::min_step_travel`]) per tick of the window, for observations that come
    /// with a position ([`observe_at`](Self::observe_at)).
    pub fn gate_stationary(mut self, min_step_travel: f64) -> Self {
        self.min_travel = min_step_travel * (self.window - 1) as f64;
        self
    }

    pub fn model(&self) -> Option<&Gmm> {
        self.model.as_ref()
    }

    pub fn stats(&self) -> OnlineStats {
        self.stats
    }

    pub fn num_envs(&self) -> usize {
        self.envs.len()
    }

    /// Forgets env `env`'s window and belief (after a respawn or teleport).
    pub fn reset_env(&mut self, env: usize) -> Result<()> {
        let envs = self.envs.len();
        let state = self
            .envs
            .get_mut(env)
            .ok_or(EstimatorError::EnvOutOfRange { env, envs })?;
        state.rolling.clear();
        state.travel.clear();
        state.belief.clear();
        state.held = None;
        Ok(())
    }

    /// Keeps env `env`'s window and belief across a placement (`estimator.on-placement =
    /// "carry"`): its next position adds no path.
    pub fn jump_env(&mut self, env: usize) -> Result<()> {
        let envs = self.envs.len();
        self.envs
            .get_mut(env)
            .ok_or(EstimatorError::EnvOutOfRange { env, envs })?
            .travel
            .jump();
        Ok(())
    }

    /// Feeds env `env`'s sin θx for this tick and returns its estimate. A non-finite value is
    /// refused (and not fed), so one bad sample cannot poison the window.
    pub fn observe(&mut self, env: usize, sin_pitch: f64) -> Result<Estimate> {
        self.observe_at(env, sin_pitch, None)
    }

    /// As [`observe`](Self::observe), with the robot's X-Z position for the stationary gate
    /// ([`gate_stationary`](Self::gate_stationary)).
    pub fn observe_at(
        &mut self,
        env: usize,
        sin_pitch: f64,
        position: Option<[f64; 2]>,
    ) -> Result<Estimate> {
        let envs = self.envs.len();
        if env >= envs {
            return Err(EstimatorError::EnvOutOfRange { env, envs });
        }
        if !sin_pitch.is_finite() {
            return Err(EstimatorError::NonFiniteObservation {
                env,
                value: sin_pitch,
            });
        }
        let (window_std, moving) = self.feed(env, sin_pitch, position);
        let pending = Estimate {
            class: None,
            posterior: 0.0,
            raw_class: None,
            window_std,
            window: self.window,
        };
        let (Some(s), Some(model)) = (window_std, self.model.as_ref()) else {
            return Ok(pending);
        };
        if !moving {
            return Ok(match self.envs[env].held {
                Some((class, posterior)) => Estimate {
                    class: Some(class),
                    posterior,
                    ..pending
                },
                None => pending,
            });
        }
        let k = model.components();
        if self.scratch.len() < k {
            self.scratch.resize(k, 0.0);
        }
        // One pass of ln(w_k N_k(s)) serves both the raw posterior and the HMM emission.
        let joint = &mut self.scratch[..k];
        let log_evidence = model.joint_log(self.feature.of(s), joint);
        let raw_class = argmax(joint);
        let raw_posterior = (joint[raw_class] - log_evidence).exp();
        let (class, posterior) = if self.stay_prob <= 0.0 {
            (raw_class, raw_posterior)
        } else {
            let evidence = 1.0 / self.window as f64;
            filter(
                &mut self.envs[env].belief,
                joint,
                model,
                evidence,
                self.stay_prob,
            )
        };
        self.envs[env].held = Some((class, posterior));
        Ok(Estimate {
            class: Some(class),
            posterior,
            raw_class: Some(raw_class),
            ..pending
        })
    }

    /// Feeds env `env`'s value into its window, the pool and the counters, refitting when
    /// due; returns the window's std once it is full, and whether the robot moved enough
    /// over the window to classify it.
    fn feed(
        &mut self,
        env: usize,
        sin_pitch: f64,
        position: Option<[f64; 2]>,
    ) -> (Option<f64>, bool) {
        let state = &mut self.envs[env];
        let window_std = state.rolling.push(sin_pitch);
        let moving = position
            .and_then(|p| state.travel.push(p))
            .is_none_or(|path| path >= self.min_travel);
        match (window_std, moving) {
            (Some(s), true) => self.pool.push(self.feature.of(s)),
            (Some(_), false) => self.stats.stationary += 1,
            (None, _) => {}
        }
        self.stats.observations += 1;
        self.maybe_refit();
        (window_std, moving)
    }

    fn maybe_refit(&mut self) {
        if self.stats.observations < self.next_fit_at || self.pool.values.len() < self.min_first_fit
        {
            return;
        }
        self.next_fit_at = self.stats.observations.saturating_add(self.refit_interval);
        let outcome = match &self.model {
            None => gmm::fit(&self.pool.values, &self.opts),
            Some(previous) => gmm::fit_from(&self.pool.values, previous, &self.opts),
        };
        match outcome {
            Ok(report) => {
                self.stats.fits += 1;
                self.model = Some(report.model);
            }
            Err(error) => {
                self.stats.failed_fits += 1;
                tracing::warn!(%error, pool = self.pool.values.len(), "terrain mixture fit failed; keeping the previous model");
            }
        }
    }
}

/// The HMM-filtered class and its probability: `belief` (started at the mixing weights of
/// `model` when it has no entry per component) after one forward step on the joint
/// log-densities `joint`, which become the emission log-densities.
fn filter(
    belief: &mut Vec<f64>,
    joint: &mut [f64],
    model: &Gmm,
    evidence: f64,
    stay: f64,
) -> (usize, f64) {
    let k = model.components();
    if belief.len() != k {
        belief.clear();
        belief.extend_from_slice(model.weights());
    }
    for (l, lw) in joint.iter_mut().zip(model.log_weights()) {
        *l -= lw;
    }
    hmm_forward(belief, joint, evidence, stay);
    let class = argmax(belief);
    (class, belief[class])
}

/// One forward-filter step: predict with the sticky transition, weight by the emission
/// log-densities `log_emission` (read only) raised to `evidence`, normalise. Every predicted
/// probability is at least `min(stay, (1 − stay)/(K − 1)) > 0`, so the belief never
/// collapses to all zeros.
fn hmm_forward(belief: &mut [f64], log_emission: &[f64], evidence: f64, stay: f64) {
    let k = belief.len();
    let switch = if k > 1 {
        (1.0 - stay) / (k - 1) as f64
    } else {
        0.0
    };
    let pivot = log_emission
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let mut total = 0.0;
    for (b, l) in belief.iter_mut().zip(log_emission.iter()) {
        let predicted = stay * *b + switch * (1.0 - *b);
        *b = predicted * (evidence * (l - pivot)).exp();
        total += *b;
    }
    for b in belief.iter_mut() {
        *b /= total;
    }
}

fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best
}

#[cfg(test)]
mod tests;
