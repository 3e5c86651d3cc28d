//! `[estimator]`: terrain estimation (SPEC S7) and the feature its mixture is fitted on.

use super::range::{count_in, in_range, invalid};
use super::{AttitudeSource, ConfigError};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Terrain estimation (SPEC S7) and switching (SPEC S8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct EstimatorConfig {
    /// Rolling-window sizes analysed offline, ticks (SPEC S7). Each 2 ..= 10^5. Default [10, 20, 40, 70].
    pub windows: Vec<usize>,
    /// Window used online, ticks. 2 ..= 10^5. Default 70 (the paper's best).
    pub online_window: usize,
    /// Ticks dropped at the start of each series (SPEC S7). 0 ..= 10^6. Default 100.
    pub warmup_ticks: usize,
    /// Mixture components (terrain classes). 2 ..= 16. Default 2.
    pub components: usize,
    /// EM restarts from different initialisations; the best likelihood wins. 1 ..= 100. Default 5.
    pub restarts: usize,
    /// EM iteration cap. 1 ..= 10^5. Default 500.
    pub max_iter: usize,
    /// EM stops when the mean log-likelihood improves by less than this. (0, 1]. Default 1e-8.
    pub tol: f64,
    /// Variance floor of each component. (0, 1]. Default 1e-10.
    pub var_floor: f64,
    /// Hold the mixing weights at 1/K instead of fitting them (interpretation; SPEC S7's
    /// mixture fits them). Default false. A terrain whose windows are not one Gaussian (its
    /// envs differ in level) lets free weights settle on a sub-cluster with a higher
    /// likelihood than the split by terrain; collection drives every area alike, so equal
    /// weights are also the prior the data was drawn with. Wrong for data far from equal
    /// shares: at 90 / 10 the fit splits the larger terrain instead.
    pub equal_weights: bool,
    /// Online: refit the mixture every this many ticks; 0 never refits (the first fit, or
    /// `model`, classifies throughout). 0 ..= 10^6. Default 500.
    pub refit_every: usize,
    /// Online: most recent window-std values kept for refitting. 10 ..= 10^7. Default 20000.
    pub pool_size: usize,
    /// Online: probability of staying on the same terrain per tick in the HMM filter; 0 disables the filter. [0, 1). Default 0.98.
    pub stay_prob: f64,
    /// A window in which the robot's mean speed over the ground (path length ÷ window
    /// duration) is below this says nothing about the terrain: a robot wedged on a bump
    /// holds its pitch still and reads as flat ground. Such windows are left out of every fit
    /// and score, offline (SPEC S7) and online, where the env keeps its previous estimate.
    /// m/s, [0, 10]; 0 counts every window, as the paper did. Default 0.02 (interpretation:
    /// a quarter of the robot's usual 0.08 m/s, so a window counts once most of it is driven).
    pub min_speed: f64,
    /// Online: a robot placed somewhere new (a respawn, or an evaluation course's next leg)
    /// starts a new window, and this many ticks, the placement's own first, are left out
    /// while the dropped robot settles; meanwhile the env has no estimate and switching keeps
    /// its slot. 0 ..= 1000. Default 3 (a drop shakes sin θx for about three ticks).
    pub settle_ticks: usize,
    /// Online: a mixture fitted offline to classify with from the first full window (SPEC
    /// S7): a `results.json` of `estimator-proc analyze`, whose fit for `online-window` is
    /// taken; refits warm-start from it. Without one the first online fit defines the
    /// classes, so it needs every terrain in its pool: a run on one terrain would split it
    /// into two. Relative to the config file. Default none.
    pub model: Option<PathBuf>,
    /// What the mixture is fitted on, offline and online: "std", each window's std of
    /// sin θx (SPEC S7), or "log-std", its natural log (interpretation). Default "std".
    pub feature: MixtureFeature,
    /// Where each tick's sin θx comes from, offline and online: "truth", the simulator's
    /// pose (SPEC S7), or "imu", the orientation filter on the simulated IMU (needs
    /// `sim.observation = "imu"` or `sim.imu.simulate = true`). Default "truth".
    pub signal: AttitudeSource,
    /// What describes a window for `estimator-proc kinds` (not in the paper): one or more of
    /// "pitch-std" (SPEC S7's feature), "roll-std", "mean-tilt", "pitch-high-pass", "slip";
    /// each documented on [`WindowFeature`]. Default ["pitch-std"].
    pub features: Vec<WindowFeature>,
    /// The several-feature mixture's covariances: "full" or "diagonal". Default "full".
    pub covariance: Covariance,
    /// How `estimator-proc kinds` fits its mixture: "em", EM without the labels, each
    /// component then named after a kind by them, or "labelled", one component per kind fitted
    /// to that kind's windows alone (interpretation). Default "em".
    pub kinds_fit: KindsFit,
    /// A window farther than this many standard deviations (Mahalanobis) from every
    /// component is "unknown" rather than any kind; 0 classifies every window. [0, 100].
    /// Default 0.
    pub unknown_beyond: f64,
    /// Online, beyond SPEC S7: a `kinds.json` of `estimator-proc kinds` whose classifier
    /// for `online-window` names each env's windows after terrain kinds, over its own
    /// features; estimates are kind codes (`AreaKind::code`), so `sim.acting = "switch"`
    /// picks among the specialists of every kind. Never refitted; excludes `model`.
    /// Relative to the config file. Default none.
    pub kinds_model: Option<PathBuf>,
}

/// A number that describes one window of one robot's ticks, and what it separates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WindowFeature {
    /// The std of sin θx (SPEC S7): bumps pitch the robot; high on rough ground, low on flat.
    PitchStd,
    /// The std of sin θz: bumps under one wheel roll the robot; rough against flat, as pitch,
    /// and a slope crossed at an angle.
    RollStd,
    /// The mean tilt of the chassis from upright, `acos(cos θx cos θz)`, radians: a slope
    /// tilts the robot whichever way it drives; bumps average out.
    MeanTilt,
    /// The RMS of sin θx's second difference per tick: what changes within a few ticks. Small
    /// dense stones (gravel) raise it more than rough ground's wider bumps.
    PitchHighPass,
    /// `1 − path ÷ commanded path` (the wheels' mean command × wheel radius × time): wheels
    /// that turn without moving the robot, on low-friction ground or a climb.
    Slip,
}

impl WindowFeature {
    pub fn name(self) -> &'static str {
        match self {
            WindowFeature::PitchStd => "pitch-std",
            WindowFeature::RollStd => "roll-std",
            WindowFeature::MeanTilt => "mean-tilt",
            WindowFeature::PitchHighPass => "pitch-high-pass",
            WindowFeature::Slip => "slip",
        }
    }
}

/// The covariance of each component of the several-feature mixture.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Covariance {
    /// A full d × d matrix: features may correlate within a terrain.
    #[default]
    Full,
    /// Variances only: d parameters per component, for few windows or many features.
    Diagonal,
}

/// How the several-kind mixture is fitted to a labelled recording.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum KindsFit {
    /// EM over every window, labels unused; the labels only name the components.
    #[default]
    Em,
    /// Each kind's component is the Gaussian of its own windows: weight, mean and covariance,
    /// no EM (quadratic discriminant analysis). A kind whose windows are not one Gaussian
    /// still gets one component, so no restart can split a kind or merge two.
    Labelled,
}

/// The value of a window the terrain mixture sees (SPEC S7: the window's std of sin θx).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MixtureFeature {
    /// The std itself, as the paper.
    #[default]
    Std,
    /// Its natural log, floored at [`MixtureFeature::LOG_FLOOR`]. A window's std is
    /// positive and skewed to the right, most on rough ground, where a few bumpy windows
    /// stretch one Gaussian so wide that it takes in the upper half of flat ground; in log
    /// space both terrains are closer to Gaussian.
    LogStd,
}

impl MixtureFeature {
    /// The std below which `log-std` reads the floor (a robot standing perfectly still).
    pub const LOG_FLOOR: f64 = 1e-6;

    /// The feature of a window whose std of sin θx is `std`.
    pub fn of(self, std: f64) -> f64 {
        match self {
            MixtureFeature::Std => std,
            MixtureFeature::LogStd => std.max(Self::LOG_FLOOR).ln(),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MixtureFeature::Std => "std",
            MixtureFeature::LogStd => "log-std",
        }
    }
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            windows: vec![10, 20, 40, 70],
            online_window: 70,
            warmup_ticks: 100,
            components: 2,
            restarts: 5,
            max_iter: 500,
            tol: 1e-8,
            var_floor: 1e-10,
            equal_weights: false,
            refit_every: 500,
            pool_size: 20_000,
            stay_prob: 0.98,
            min_speed: 0.02,
            model: None,
            feature: MixtureFeature::Std,
            signal: AttitudeSource::Truth,
            features: vec![WindowFeature::PitchStd],
            covariance: Covariance::Full,
            kinds_fit: KindsFit::Em,
            unknown_beyond: 0.0,
            kinds_model: None,
            settle_ticks: 3,
        }
    }
}

impl EstimatorConfig {
    /// Ranges, then the offline model the config names, if any.
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        if self.windows.is_empty() {
            return Err(invalid(
                "estimator.windows",
                &self.windows,
                "needs at least one window",
            ));
        }
        for &w in &self.windows {
            count_in("estimator.windows", w, 2, 100_000)?;
        }
        count_in("estimator.online-window", self.online_window, 2, 100_000)?;
        count_in("estimator.warmup-ticks", self.warmup_ticks, 0, 1_000_000)?;
        count_in("estimator.components", self.components, 2, 16)?;
        count_in("estimator.restarts", self.restarts, 1, 100)?;
        count_in("estimator.max-iter", self.max_iter, 1, 100_000)?;
        in_range("estimator.tol", self.tol, 1e-15, 1.0)?;
        in_range("estimator.var-floor", self.var_floor, 1e-15, 1.0)?;
        in_range("estimator.min-speed", self.min_speed, 0.0, 10.0)?;
        count_in("estimator.settle-ticks", self.settle_ticks, 0, 1000)?;
        count_in("estimator.refit-every", self.refit_every, 0, 1_000_000)?;
        count_in("estimator.pool-size", self.pool_size, 10, 10_000_000)?;
        if !(self.stay_prob.is_finite() && (0.0..1.0).contains(&self.stay_prob)) {
            return Err(invalid(
                "estimator.stay-prob",
                self.stay_prob,
                "must be in [0, 1)",
            ));
        }
        if self.features.is_empty() || self.features.len() > 16 {
            return Err(invalid(
                "estimator.features",
                &self.features,
                "needs 1 to 16 features",
            ));
        }
        if let Some(f) = self
            .features
            .iter()
            .enumerate()
            .find_map(|(i, f)| self.features[..i].contains(f).then_some(f))
        {
            return Err(invalid(
                "estimator.features",
                f.name(),
                "names a feature twice",
            ));
        }
        in_range("estimator.unknown-beyond", self.unknown_beyond, 0.0, 100.0)?;
        if self.model.is_some() && self.kinds_model.is_some() {
            return Err(invalid(
                "estimator.kinds-model",
                &self.kinds_model,
                "excludes estimator.model: give one classifier",
            ));
        }
        self.offline_mixture()?;
        self.offline_kinds()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mixture_feature_is_the_std_or_its_floored_log() {
        assert_eq!(MixtureFeature::Std.of(0.05), 0.05);
        assert_eq!(MixtureFeature::LogStd.of(std::f64::consts::E), 1.0);
        assert_eq!(MixtureFeature::LogStd.of(0.0), (1e-6f64).ln());
    }
}
