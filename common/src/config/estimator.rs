//! `[estimator]`: terrain estimation (SPEC S7) and the feature its mixture is fitted on.

use super::range::invalid;
use super::setting::{Setting, choices, count, flag, form, real, settings};
use super::{AttitudeSource, ConfigError};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The window sizes a rolling window may have, ticks (`windows`, `online-window` and the
/// command lines that take a window).
pub const WINDOW_TICKS: (u64, u64) = (2, 100_000);

settings! {
    /// Terrain estimation (SPEC S7) and switching (SPEC S8).
    pub struct EstimatorConfig {
        /// Rolling-window sizes analysed offline (SPEC S7); at least one.
        pub windows: Vec<usize> = vec![10, 20, 40, 70]
            => count(WINDOW_TICKS.0, WINDOW_TICKS.1), "ticks", Advanced;
        /// Window used online (70: the paper's best).
        pub online_window: usize = 70 => count(WINDOW_TICKS.0, WINDOW_TICKS.1), "ticks", Advanced;
        /// Ticks dropped at the start of each series (SPEC S7).
        pub warmup_ticks: usize = 100 => count(0, 1_000_000), "ticks", Advanced;
        /// Mixture components (terrain classes).
        pub components: usize = 2 => count(2, 16), "components", Advanced;
        /// EM restarts from different initialisations; the best likelihood wins.
        pub restarts: usize = 5 => count(1, 100), "fits", Advanced;
        /// EM iteration cap.
        pub max_iter: usize = 500 => count(1, 100_000), "iterations", Advanced;
        /// EM stops when the mean log-likelihood improves by less than this.
        pub tol: f64 = 1e-8 => real(1e-15, 1.0), "", Advanced;
        /// Variance floor of each component.
        pub var_floor: f64 = 1e-10 => real(1e-15, 1.0), "", Advanced;
        /// Hold the mixing weights at 1/K instead of fitting them (interpretation; SPEC S7's
        /// mixture fits them). A terrain whose windows are not one Gaussian (its envs differ
        /// in level) lets free weights settle on a sub-cluster with a higher likelihood than
        /// the split by terrain; collection drives every area alike, so equal weights are
        /// also the prior the data was drawn with. Wrong for data far from equal shares: at
        /// 90 / 10 the fit splits the larger terrain instead.
        pub equal_weights: bool = false => flag(), "", Research;
        /// Online: refit the mixture every this many ticks; 0 never refits (the first fit, or
        /// `model`, classifies throughout).
        pub refit_every: usize = 500 => count(0, 1_000_000), "ticks", Advanced;
        /// Online: most recent window-std values kept for refitting.
        pub pool_size: usize = 20_000 => count(10, 10_000_000), "values", Advanced;
        /// Online: probability of staying on the same terrain per tick in the HMM filter,
        /// below 1; 0 disables the filter.
        pub stay_prob: f64 = 0.98 => real(0.0, 1.0), "", Advanced;
        /// A window in which the robot's mean speed over the ground (path length ÷ window
        /// duration) is below this says nothing about the terrain: a robot wedged on a bump
        /// holds its pitch still and reads as flat ground. Such windows are left out of every
        /// fit and score, offline (SPEC S7) and online, where the env keeps its previous
        /// estimate. 0 counts every window, as the paper did; 0.02 (interpretation) is a
        /// quarter of the robot's usual 0.08 m/s, so a window counts once most of it is driven.
        pub min_speed: f64 = 0.02 => real(0.0, 10.0), "m/s", Research;
        /// Online: after a robot is placed somewhere new (a respawn, or an evaluation course's
        /// next leg) this many ticks, the placement's own first, are left out while the
        /// dropped robot settles (a drop shakes sin θx for about three ticks).
        pub settle_ticks: usize = 3 => count(0, 1000), "ticks", Advanced;
        /// Online: what a placement does to the env's window: `carry` keeps it and its
        /// estimate (the jump adds no path), `new-window` starts a new one, without an
        /// estimate until it fills (docs/EXPERIMENT.md E17).
        pub on_placement: OnPlacement = OnPlacement::Carry => choices::<OnPlacement>(), "", Research;
        /// Online: a mixture fitted offline to classify with from the first full window (SPEC
        /// S7): a `results.json` of `estimator-proc analyze`, whose fit for `online-window` is
        /// taken; refits warm-start from it. Without one the first online fit defines the
        /// classes, so it needs every terrain in its pool: a run on one terrain would split it
        /// into two. Relative to the config file; unset: none.
        pub model: Option<PathBuf> = None => form("a results.json file"), "", Essential;
        /// What the mixture is fitted on, offline and online: `std`, each window's std of
        /// sin θx (SPEC S7), or `log-std`, its natural log (interpretation).
        pub feature: MixtureFeature = MixtureFeature::Std => choices::<MixtureFeature>(), "", Research;
        /// Where each tick's sin θx comes from, offline and online: `truth`, the simulator's
        /// pose (SPEC S7), or `imu`, the orientation filter on the simulated IMU (needs
        /// `sim.observation = "imu"` or `sim.imu.simulate = true`).
        pub signal: AttitudeSource = AttitudeSource::Truth => choices::<AttitudeSource>(), "", Research;
        /// What describes a window for `estimator-proc kinds` (not in the paper): 1 to 16
        /// features, none twice, each documented on [`WindowFeature`].
        pub features: Vec<WindowFeature> = vec![WindowFeature::PitchStd] => choices::<WindowFeature>(), "", Research;
        /// The several-feature mixture's covariances: `full` or `diagonal`.
        pub covariance: Covariance = Covariance::Full => choices::<Covariance>(), "", Research;
        /// How `estimator-proc kinds` fits its mixture: `em`, EM without the labels, each
        /// component then named after a kind by them, or `labelled`, one component per kind
        /// fitted to that kind's windows alone (interpretation).
        pub kinds_fit: KindsFit = KindsFit::Em => choices::<KindsFit>(), "", Research;
        /// `estimator-proc kinds` with `kinds-fit = "em"`: mixture components per kind, for
        /// kinds whose windows are not one Gaussian (a robot that drives, and one dug in).
        pub components_per_kind: usize = 1 => count(1, 8), "components", Research;
        /// A window farther than this many standard deviations (Mahalanobis) from every
        /// component is "unknown" rather than any kind; 0 classifies every window.
        pub unknown_beyond: f64 = 0.0 => real(0.0, 100.0), "σ", Research;
        /// Online, beyond SPEC S7: a `kinds.json` of `estimator-proc kinds` whose classifier
        /// for `online-window` names each env's windows after terrain kinds, over its own
        /// features; estimates are kind codes (`AreaKind::code`), so `sim.acting = "switch"`
        /// picks among the specialists of every kind. Never refitted; excludes `model`.
        /// Relative to the config file; unset: none.
        pub kinds_model: Option<PathBuf> = None => form("a kinds.json file"), "", Essential;
    }
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

impl Setting for WindowFeature {}

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

impl Setting for Covariance {}

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

impl Setting for KindsFit {}

/// What a placement does to an env's online window (`estimator.on-placement`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnPlacement {
    /// Keep the window and the estimate; the settling ticks are left out and the placement's
    /// jump adds no path, so a robot's windows run on as one drive.
    #[default]
    Carry,
    /// Start a new window: no estimate until it fills.
    NewWindow,
}

impl Setting for OnPlacement {}

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

impl Setting for MixtureFeature {}

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

impl EstimatorConfig {
    /// The rules between fields (each field's own range is [`Setting::check`]'s), then the
    /// offline model the config names, if any.
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        if self.windows.is_empty() {
            return Err(invalid(
                "estimator.windows",
                &self.windows,
                "needs at least one window",
            ));
        }
        if self.stay_prob >= 1.0 {
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
