//! Stage e's choice of how switching reads the ground (EXPERIMENT E21): with
//! `reproduce.switch-windows` or `reproduce.switch-dwells`, switching between the chosen
//! specialists drives the mixed validation courses once per online window × dwell, and the
//! best of them (success, then reach time, as the specialists are chosen) drives stage f.
//! Kept in `e-switch/tuning.json`.

use super::legs::{Cell, Legs};
use super::selection::best;
use super::stages::Pipeline;
use anyhow::Context;
use common::Config;
use common::config::{AreaKind, PolicySlot};
use common::coverage::Coverage;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// How switching reads the ground: the online window and the dwell a new estimate holds
/// before an env changes policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(super) struct Reading {
    pub(super) window: usize,
    pub(super) dwell: usize,
}

impl Reading {
    /// The config's own: `estimator.online-window` and `sim.switch-dwell`.
    pub(super) fn of(cfg: &Config) -> Self {
        Self {
            window: cfg.estimator.online_window,
            dwell: cfg.sim.switch_dwell,
        }
    }

    /// `cfg` reading the ground this way.
    pub(super) fn apply(self, cfg: &mut Config) {
        cfg.estimator.online_window = self.window;
        cfg.sim.switch_dwell = self.dwell;
    }

    /// The name of its runs: `w70-d10`.
    pub(super) fn label(self) -> String {
        format!("w{}-d{}", self.window, self.dwell)
    }
}

/// One reading tried on the validation courses.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Tried {
    pub(super) reading: Reading,
    pub(super) cell: Cell,
    pub(super) coverage: Coverage,
}

/// Stage e-switch's readings and the one chosen.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Tuning {
    pub(super) tried: Vec<Tried>,
    pub(super) chosen: usize,
}

impl Tuning {
    pub(super) fn reading(&self) -> Reading {
        self.tried[self.chosen].reading
    }
}

const STAGE: &str = "e-switch";
const TUNING_JSON: &str = "tuning.json";

/// Every window × dwell of `[reproduce]`, the config's own reading first so that it is kept
/// among equals; an empty list stands for the config's own value.
pub(super) fn candidates(cfg: &Config) -> Vec<Reading> {
    let own = Reading::of(cfg);
    let r = &cfg.reproduce;
    let or_own = |list: &[usize], v: usize| {
        if list.is_empty() {
            vec![v]
        } else {
            list.to_vec()
        }
    };
    let mut all = vec![own];
    for window in or_own(&r.switch_windows, own.window) {
        for dwell in or_own(&r.switch_dwells, own.dwell) {
            let reading = Reading { window, dwell };
            if !all.contains(&reading) {
                all.push(reading);
            }
        }
    }
    all
}

/// Stage e-switch's choice, if it finished.
pub(super) fn tuned_before(p: &Pipeline) -> anyhow::Result<Option<Tuning>> {
    p.kept(STAGE, TUNING_JSON, "stage e's choice of reading")
}

impl Pipeline {
    /// How stage f's switching reads the ground: the config's own with one candidate (or when
    /// stage f finished before any choice), else the best of them on the mixed validation
    /// courses, chosen once and kept.
    pub(super) fn reading(
        &self,
        frozen: &BTreeMap<PolicySlot, PathBuf>,
    ) -> anyhow::Result<(Reading, Option<Tuning>)> {
        let all = candidates(&self.base);
        if all.len() < 2 {
            return Ok((all[0], None));
        }
        if let Some(tuning) = tuned_before(self)? {
            return Ok((tuning.reading(), Some(tuning)));
        }
        if self.done("f-eval") {
            // Stage f drove before any reading was chosen: a choice now would not be the one
            // its cells drove with.
            return Ok((all[0], None));
        }
        let dir = self.stage_dir(STAGE);
        std::fs::create_dir_all(self.fresh(STAGE)?)?;
        self.say(&format!(
            "{STAGE}: switching with {} online windows × dwells on the mixed validation courses",
            all.len()
        ));
        let courses = self.validation_courses(STAGE);
        let mut tried = Vec::new();
        let mut legs: Vec<Legs> = Vec::new();
        for reading in all {
            let model = format!("switching-{}", reading.label());
            let driven = self.switching(&model, AreaKind::Mixed, frozen, &dir, courses, reading)?;
            tried.push(Tried {
                reading,
                cell: Cell::of(&driven.legs, self.base.sim.decision_dt()),
                coverage: driven
                    .coverage
                    .context("a switching evaluation counts its coverage")?,
            });
            legs.push(driven.legs);
        }
        let chosen = best(&legs, self.base.reproduce.margin_pp);
        let tuning = Tuning { tried, chosen };
        self.say(&format!(
            "{STAGE}: window {} ticks, dwell {} ticks",
            tuning.reading().window,
            tuning.reading().dwell
        ));
        std::fs::write(dir.join(TUNING_JSON), serde_json::to_string(&tuning)?)?;
        self.finish(STAGE, serde_json::json!({ "tried": tuning.tried.len() }))?;
        Ok((tuning.reading(), Some(tuning)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_cross_windows_and_dwells_with_the_config_s_own_first() {
        let mut cfg = Config::default();
        assert_eq!(
            candidates(&cfg),
            [Reading {
                window: 70,
                dwell: 10
            }],
            "the paper's: one reading, no stage"
        );
        cfg.reproduce.switch_windows = vec![20, 70];
        let got: Vec<String> = candidates(&cfg).into_iter().map(Reading::label).collect();
        assert_eq!(got, ["w70-d10", "w20-d10"]);
        cfg.reproduce.switch_dwells = vec![5, 10];
        let got: Vec<String> = candidates(&cfg).into_iter().map(Reading::label).collect();
        assert_eq!(got, ["w70-d10", "w20-d5", "w20-d10", "w70-d5"]);
        let mut applied = Config::default();
        Reading {
            window: 20,
            dwell: 5,
        }
        .apply(&mut applied);
        assert_eq!(Reading::of(&applied).label(), "w20-d5");
    }
}
