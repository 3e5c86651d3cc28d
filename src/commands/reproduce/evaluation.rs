//! Stage f's evaluation and stage e's validation: every model drives the same seeded
//! courses, alone in `sim-proc` or switching through the full runtime.

use super::legs::{Cell, Evaluated, Legs, legs_in};
use super::stages::Pipeline;
use super::tuning::Reading;
use crate::runtime::{self, coverage_line};
use anyhow::Context;
use common::Config;
use common::config::{Acting, AreaKind, EpisodeStart, PolicySlot};
use common::coverage::Coverage;
use common::run_dir::TELEMETRY_CSV;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where stage f evaluates every model: each terrain kind's area (SPEC S8's flat and rough
/// on the paper's world), then the mixed course.
pub(super) fn eval_areas(kinds: &[AreaKind]) -> Vec<AreaKind> {
    kinds
        .iter()
        .copied()
        .chain(std::iter::once(AreaKind::Mixed))
        .collect()
}

/// Validation courses' seeds start this far from the run's, so stage e's choice of
/// specialist never drives stage f's courses.
const VALIDATION_SEEDS: u64 = 1 << 20;

/// The courses an evaluation drives: the stage that drives them (for progress lines), the
/// first seed (a cell short of its episodes drives the next), the episodes a cell needs, and
/// the ticks per env of one run.
#[derive(Debug, Clone, Copy)]
pub(super) struct Courses {
    stage: &'static str,
    seed: u64,
    episodes: u64,
    ticks: u64,
}

/// Stage f's guess at the ticks an evaluation episode lasts, to size its runs: trained
/// models reach the target in about 40 (3.5-4 s at 0.1 s per tick).
const EPISODE_TICKS_GUESS: u64 = 50;

/// `sim-proc` alone with a policy file: `steps` decision steps per env, telemetry to `csv`
/// (its config beside it, `.toml`, and its output, `.log`).
pub(crate) fn drive(cfg: &Config, weights: &Path, steps: u64, csv: &Path) -> anyhow::Result<()> {
    let dir = csv.parent().unwrap_or(Path::new("."));
    let cfg_path = csv.with_extension("toml");
    std::fs::write(&cfg_path, cfg.to_toml())
        .with_context(|| format!("cannot write {}", cfg_path.display()))?;
    let run = Command::new(runtime::locate("sim-proc")?)
        .arg("--config")
        .arg(&cfg_path)
        .args(["--controller", "policy", "--weights"])
        .arg(weights)
        .args(["--steps", &steps.to_string(), "--telemetry"])
        .arg(csv)
        .current_dir(dir)
        .output()?;
    let log = csv.with_extension("log");
    std::fs::write(&log, [run.stdout, run.stderr].concat())
        .with_context(|| format!("cannot write {}", log.display()))?;
    anyhow::ensure!(
        run.status.success(),
        "sim-proc on {} failed; see {}",
        weights.display(),
        log.display()
    );
    Ok(())
}

/// Drives `cfg`'s courses until `episodes` have ended: runs `run_part` (the config and the
/// part's index; returns its telemetry CSV) with seeds `cfg.run.seed`, +1, … Every model
/// driven so runs the same seeds on the same courses, so their legs pair up.
pub(crate) fn drive_courses(
    cfg: &Config,
    episodes: u64,
    mut run_part: impl FnMut(&Config, usize) -> anyhow::Result<PathBuf>,
) -> anyhow::Result<Legs> {
    let mut cfg = cfg.clone();
    let mut legs = Legs::new();
    let dt = cfg.sim.decision_dt();
    while Cell::of(&legs, dt).episodes < episodes {
        let csv = run_part(&cfg, legs.len())?;
        let part = legs_in(&csv)?;
        anyhow::ensure!(
            part.iter().any(|env| !env.is_empty()),
            "{} holds no finished episode",
            csv.display()
        );
        legs.push(part);
        cfg.run.seed = cfg.run.seed.wrapping_add(1);
    }
    Ok(legs)
}

/// Ticks per env of one course run of `cfg` for `episodes` over `envs` envs: enough for the
/// episodes at `EPISODE_TICKS_GUESS` ticks each, and for every env to end one episode
/// however long it lasts. A cell short of its episodes runs again with the next seed.
pub(crate) fn course_ticks(cfg: &Config, episodes: u64, envs: u64) -> u64 {
    (episodes.div_ceil(envs) * EPISODE_TICKS_GUESS).max(cfg.sim.task.longest_episode_ticks() + 1)
}

impl Pipeline {
    /// Evaluates `model` in `area` on `courses`: runs `run_part` (the config, the part's
    /// name; returns its telemetry CSV) with seeds `courses.seed`, +1, … until the cell has
    /// its episodes. Every model runs the same seeds on the same courses, so their legs pair up.
    fn evaluate(
        &self,
        model: &str,
        area: AreaKind,
        courses: Courses,
        mut run_part: impl FnMut(&Config, &str) -> anyhow::Result<PathBuf>,
    ) -> anyhow::Result<Evaluated> {
        let mut cfg = self.eval_in(area);
        cfg.run.seed = courses.seed;
        let legs = drive_courses(&cfg, courses.episodes, |cfg, part| {
            run_part(
                cfg,
                &format!("{}-{}-{part}", model.to_lowercase(), area.name()),
            )
        })?;
        let cell = Cell::of(&legs, cfg.sim.decision_dt());
        self.say(&format!(
            "{}: {model} on {} ground: {:.1}% of {} episodes, reach s {}",
            courses.stage,
            area.name(),
            cell.success_pct(),
            cell.episodes,
            cell.reach()
        ));
        Ok(Evaluated {
            model: model.into(),
            area,
            legs,
            coverage: None,
        })
    }

    /// `weights` alone (`sim-proc`) on `courses` in `area`, its telemetry in `dir`.
    pub(super) fn evaluate_policy(
        &self,
        model: &str,
        weights: &Path,
        area: AreaKind,
        courses: Courses,
        dir: &Path,
    ) -> anyhow::Result<Evaluated> {
        self.evaluate(model, area, courses, |cfg, part| {
            let csv = dir.join(format!("{part}.csv"));
            drive(cfg, weights, courses.ticks, &csv)?;
            Ok(csv)
        })
    }

    /// SPEC S8's switching policy in `area` on `courses`, run as `model` in `eval`: the
    /// specialists (FTM and RTM on the paper's terrains) served frozen, each env acting with
    /// the one its live terrain estimate points to (mean actions), through the full runtime
    /// with the estimator reading the ground as `reading` says.
    pub(super) fn switching(
        &self,
        model: &str,
        area: AreaKind,
        frozen: &std::collections::BTreeMap<PolicySlot, PathBuf>,
        eval: &Path,
        courses: Courses,
        reading: Reading,
    ) -> anyhow::Result<Evaluated> {
        let steps = courses.ticks * self.base.reproduce.eval_envs as u64;
        let mut recordings = Vec::new();
        let mut evaluated = self.evaluate(model, area, courses, |base, name| {
            let mut cfg = base.clone();
            reading.apply(&mut cfg);
            cfg.run.learners.clear();
            cfg.run.frozen = frozen.clone();
            cfg.run.mode = common::config::LearnMode::Async;
            cfg.run.out_dir = eval.to_path_buf();
            cfg.run.telemetry_csv = true;
            cfg.run.total_steps = steps;
            cfg.sim.acting = Acting::Switch;
            cfg.sim.mean_actions = true;
            // SPEC S7-S8: the estimator classifies with stage d's mixture, fitted on every
            // terrain, and is not refitted: a fit on one area's windows alone would split
            // that terrain into two classes and hand half of it to another specialist.
            self.estimate_with_stage_d(&mut cfg);
            cfg.validate()?;
            self.execute(&cfg, name)?;
            let csv = eval.join(name).join(TELEMETRY_CSV);
            recordings.push(csv.clone());
            Ok(csv)
        })?;
        let mut read = self.base.clone();
        reading.apply(&mut read);
        let coverage = Coverage::of_files(&recordings, &read.sim)?;
        self.say(&format!(
            "{}: {model} on {} ground: {}",
            courses.stage,
            area.name(),
            coverage_line(&coverage, self.base.sim.decision_dt())
        ));
        evaluated.coverage = Some(coverage);
        Ok(evaluated)
    }

    /// Stage f's config in `area`: `reproduce.eval-envs` envs, all there, on the
    /// evaluation's ground, each driving a seeded course (the same legs for every model).
    fn eval_in(&self, area: AreaKind) -> Config {
        let r = &self.base.reproduce;
        let mut c = self.base.clone();
        c.sim.only_in(area, r.eval_envs);
        c.sim.task.episodes = EpisodeStart::Course;
        if let Some(scale) = r.eval_roughness_scale {
            c.sim.terrain.roughness_scale = scale;
        }
        c
    }

    /// Courses of `episodes` per cell from seed `seed` on ([`course_ticks`] per run).
    fn courses(&self, stage: &'static str, seed: u64, episodes: u64) -> Courses {
        let envs = self.base.reproduce.eval_envs as u64;
        Courses {
            stage,
            seed,
            episodes,
            ticks: course_ticks(&self.base, episodes, envs),
        }
    }

    /// Stage f's courses, from the run's seed on.
    pub(super) fn test_courses(&self) -> Courses {
        let r = &self.base.reproduce;
        self.courses("f-eval", self.base.run.seed, r.eval_episodes)
    }

    /// The robustness worlds' courses: stage f's seeds, `reproduce.robustness-episodes` a
    /// cell, driven by `stage` (for progress lines).
    pub(super) fn robustness_courses(&self, stage: &'static str) -> Courses {
        let r = &self.base.reproduce;
        self.courses(stage, self.base.run.seed, r.robustness_episodes)
    }

    /// Stage e's validation courses, `VALIDATION_SEEDS` away from stage f's, driven by
    /// `stage` (for progress lines).
    pub(super) fn validation_courses(&self, stage: &'static str) -> Courses {
        let r = &self.base.reproduce;
        let seed = self.base.run.seed.wrapping_add(VALIDATION_SEEDS);
        self.courses(stage, seed, r.validation_episodes)
    }
}
