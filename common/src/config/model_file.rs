//! Reading `estimator.model`, the offline analysis's `results.json`, and
//! `estimator.kinds-model`, a `kinds.json` of `estimator-proc kinds`: each checked against
//! the config that names it.

use super::range::invalid;
use super::{AreaKind, ConfigError, EstimatorConfig, MixtureFeature, WindowFeature};
use serde::Deserialize;
use serde::de::DeserializeOwned;
use std::path::Path;

/// A terrain mixture fitted offline, as [`EstimatorConfig::model`] holds it: components by
/// ascending mean (0 = flat), over `feature` (files written before it existed: `std`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct OfflineMixture {
    pub window: usize,
    #[serde(default)]
    pub feature: MixtureFeature,
    pub weights: Vec<f64>,
    pub means: Vec<f64>,
    pub stds: Vec<f64>,
}

impl EstimatorConfig {
    /// The fit of [`model`](Self::model) for `online-window`; `None` without a model.
    pub fn offline_mixture(&self) -> Result<Option<OfflineMixture>, ConfigError> {
        let Some(path) = &self.model else {
            return Ok(None);
        };
        let bad = |reason: String| invalid("estimator.model", path, reason);
        let m: OfflineMixture = self.online_entry(
            path,
            "estimator.model",
            "the results.json of `estimator-proc analyze`",
            "fits",
            |m: &OfflineMixture| m.window,
        )?;
        if m.feature != self.feature {
            return Err(bad(format!(
                "its fit is over `{}`, but estimator.feature is `{}`",
                m.feature.name(),
                self.feature.name()
            )));
        }
        let k = self.components;
        if [&m.weights, &m.means, &m.stds].iter().any(|v| v.len() != k) {
            return Err(bad(format!(
                "its fit for window {} does not have estimator.components = {k} components",
                m.window
            )));
        }
        let finite = m.weights.iter().chain(&m.means).all(|v| v.is_finite());
        if !finite || !m.stds.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(bad(format!(
                "its fit for window {} has a non-finite parameter or a std that is not positive",
                m.window
            )));
        }
        Ok(Some(m))
    }
}

/// What the config checks of a `kinds.json` classifier (the mixture itself is read by
/// `estimator-proc`): its window, features and the kind each component stands for.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct OfflineKinds {
    pub window: usize,
    pub features: Vec<WindowFeature>,
    pub component_kinds: Vec<AreaKind>,
}

impl EstimatorConfig {
    /// The classifier of [`kinds_model`](Self::kinds_model) for `online-window`; `None`
    /// without one.
    pub fn offline_kinds(&self) -> Result<Option<OfflineKinds>, ConfigError> {
        let Some(path) = &self.kinds_model else {
            return Ok(None);
        };
        let bad = |reason: String| invalid("estimator.kinds-model", path, reason);
        let m: OfflineKinds = self.online_entry(
            path,
            "estimator.kinds-model",
            "the kinds.json of `estimator-proc kinds`",
            "classifiers",
            |m: &OfflineKinds| m.window,
        )?;
        if let Some(k) = m.component_kinds.iter().find(|k| **k == AreaKind::Mixed) {
            return Err(bad(format!(
                "names a component `{}`, not a terrain kind",
                k.name()
            )));
        }
        if m.component_kinds.is_empty() {
            return Err(bad("its classifier has no component".into()));
        }
        Ok(Some(m))
    }
}

impl EstimatorConfig {
    /// The entry for `online-window` in the `windows` list of the JSON file at `path`
    /// (`field` names the setting in errors; `file` what the file should be; `entries` what
    /// it lists).
    fn online_entry<T: DeserializeOwned>(
        &self,
        path: &Path,
        field: &'static str,
        file: &str,
        entries: &str,
        window_of: fn(&T) -> usize,
    ) -> Result<T, ConfigError> {
        #[derive(Deserialize)]
        #[serde(bound = "T: DeserializeOwned")]
        struct Windows<T> {
            windows: Vec<T>,
        }
        let bad = |reason: String| invalid(field, path, reason);
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let list: Windows<T> =
            serde_json::from_str(&text).map_err(|e| bad(format!("not {file}: {e}")))?;
        let found: Vec<usize> = list.windows.iter().map(window_of).collect();
        list.windows
            .into_iter()
            .find(|m| window_of(m) == self.online_window)
            .ok_or_else(|| {
                bad(format!(
                    "holds {entries} for windows {found:?}, none for estimator.online-window {}",
                    self.online_window
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;

    /// SPEC S7: the online estimator can start from the offline analysis's mixture for its
    /// window; a file without one is refused when the config is checked.
    #[test]
    fn an_offline_model_is_read_for_the_online_window() {
        let dir = tempfile::tempdir().expect("tempdir");
        let results = dir.path().join("results.json");
        let fit = |w: usize, std: f64| {
            format!(
                r#"{{"window": {w}, "n": 9, "weights": [0.5, 0.5], "means": [0.02, 0.08], "stds": [0.01, {std}], "accuracy": 0.9}}"#
            )
        };
        let write = |fits: &[String]| {
            let text = format!(r#"{{"input": "t.csv", "windows": [{}]}}"#, fits.join(","));
            std::fs::write(&results, text).expect("write");
        };
        write(&[fit(10, 0.04), fit(70, 0.03)]);
        let mut e = EstimatorConfig {
            model: Some(results.clone()),
            refit_every: 0,
            ..EstimatorConfig::default()
        };
        let m = e.offline_mixture().expect("read").expect("a model");
        assert_eq!(
            (m.window, m.means, m.stds),
            (70, vec![0.02, 0.08], vec![0.01, 0.03])
        );
        e.online_window = 40;
        let err = e.offline_mixture().expect_err("no fit for 40").to_string();
        assert!(
            err.contains("windows [10, 70], none for estimator.online-window 40"),
            "{err}"
        );
        e.online_window = 70;
        // A fit over log std is refused by a config that classifies the std itself.
        write(&[fit(70, 0.03).replace(r#""n": 9"#, r#""feature": "log-std", "n": 9"#)]);
        let err = e.offline_mixture().expect_err("other feature").to_string();
        assert!(
            err.contains("over `log-std`, but estimator.feature is `std`"),
            "{err}"
        );
        e.feature = MixtureFeature::LogStd;
        assert!(e.offline_mixture().expect("read").is_some());
        e.feature = MixtureFeature::Std;
        write(&[fit(70, 0.0)]);
        let err = e.offline_mixture().expect_err("zero std").to_string();
        assert!(err.contains("std that is not positive"), "{err}");
        std::fs::write(&results, "[]").expect("write");
        let err = e
            .offline_mixture()
            .expect_err("not an analysis")
            .to_string();
        assert!(err.starts_with("config field `estimator.model`"), "{err}");
        let cfg = Config {
            estimator: e,
            ..Config::default()
        };
        assert!(cfg.validate().is_err(), "checked with the config");
    }

    /// An online K-kind classifier must exist for the online window and use only features
    /// telemetry carries.
    #[test]
    fn a_kinds_model_is_read_for_the_online_window() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("kinds.json");
        let write = |window: usize, features: &str| {
            let text = format!(
                r#"{{"input": "t.csv", "windows": [{{"window": {window}, "features": [{features}], "component_kinds": ["flat", "slope", "rough"], "model": {{}}}}]}}"#
            );
            std::fs::write(&path, text).expect("write");
        };
        write(70, r#""pitch-std", "mean-tilt""#);
        let mut e = EstimatorConfig {
            kinds_model: Some(path.clone()),
            ..EstimatorConfig::default()
        };
        let m = e.offline_kinds().expect("read").expect("a model");
        assert_eq!(
            m.component_kinds,
            [AreaKind::Flat, AreaKind::Slope, AreaKind::Rough]
        );
        e.online_window = 40;
        let err = e.offline_kinds().expect_err("no window 40").to_string();
        assert!(
            err.contains("windows [70], none for estimator.online-window 40"),
            "{err}"
        );
        e.online_window = 70;
        // Telemetry carries the wheel command: a slip classifier runs online.
        write(70, r#""pitch-std", "slip""#);
        let m = e.offline_kinds().expect("slip").expect("a model");
        assert_eq!(m.features, [WindowFeature::PitchStd, WindowFeature::Slip]);
        write(70, r#""pitch-std""#);
        e.model = Some(path.clone());
        let cfg = Config {
            estimator: e,
            ..Config::default()
        };
        let err = cfg.validate().expect_err("two models").to_string();
        assert!(err.contains("estimator.kinds-model"), "{err}");
    }
}
