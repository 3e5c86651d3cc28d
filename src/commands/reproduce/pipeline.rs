//! The stages in their order (a–g, see the command's docs), each resumed or run afresh.

use super::evaluation::{drive, eval_areas};
use super::legs::Evaluated;
use super::report::report;
use super::robustness;
use super::selection::{Role, Selection, roles, specialists};
use super::stages::Pipeline;
use super::tuning::Reading;
use crate::runtime;
use anyhow::Context;
use common::config::{Acting, AreaKind, PolicySlot};
use common::{Config, run_dir};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where stage f keeps its cells.
const CELLS_JSON: &str = "cells.json";

/// Stage f's cells, if it finished.
pub(super) fn evaluated_before(p: &Pipeline) -> anyhow::Result<Option<Vec<Evaluated>>> {
    p.kept("f-eval", CELLS_JSON, "stage f's legs")
}

/// One seed's pipeline, stages a–g in `p.out`.
pub(super) fn run(p: &Pipeline) -> anyhow::Result<Vec<Evaluated>> {
    std::fs::write(p.out.join(run_dir::CONFIG_TOML), p.base.to_toml())?;
    train_flat(p)?;
    train_general(p)?;
    let policies = p.stage_dir("policies");
    std::fs::create_dir_all(&policies)?;
    let general = policies.join("general.policy");
    p.export(&p.checkpoint("b-general", PolicySlot::General)?, &general)?;
    let traces = collect(p, &general)?;
    analyse(p, &traces)?;
    let roles = roles(&p.kinds());
    train_specialists(p, &roles)?;
    let selections = specialists(p)?;
    let models = models(p, &policies, general, &roles, &selections)?;
    let frozen: BTreeMap<PolicySlot, PathBuf> = roles
        .iter()
        .map(|r| r.slot)
        .zip(selections.iter().map(|s| s.checkpoint().to_path_buf()))
        .collect();
    let (reading, tuning) = p.reading(&frozen)?;
    let cells = evaluate(p, &models, &frozen, reading)?;
    let worlds = robustness::drive(p, &policies.join("general.policy"), &frozen, reading)?;
    let report = report(p, &cells, &selections, tuning.as_ref(), worlds.as_deref())?;
    let path = p.out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    println!("report: {}", path.display());
    Ok(cells)
}

/// Stage a: the initial flat model, from scratch. One general model acts in stages a and b:
/// no env switches, so no estimator runs.
fn train_flat(p: &Pipeline) -> anyhow::Result<()> {
    let r = &p.base.reproduce;
    let mut a = p.base.clone();
    a.sim.only_in(AreaKind::Flat, r.flat_envs);
    a.run.total_steps = r.flat_steps;
    a.run.estimator = false;
    p.train("a-flat", a)
}

/// Stage b: the general model on every terrain kind's area, warm-started from stage a.
fn train_general(p: &Pipeline) -> anyhow::Result<()> {
    let r = &p.base.reproduce;
    let mut b = p.envs(r.envs_per_area);
    b.run.total_steps = r.general_steps;
    b.run.init_from = Some(p.checkpoint("a-flat", PolicySlot::General)?);
    b.run.estimator = false;
    p.train("b-general", b)
}

/// Stage c: telemetry of the general model's policy file `general` in every area; where it
/// is.
fn collect(p: &Pipeline, general: &Path) -> anyhow::Result<PathBuf> {
    let r = &p.base.reproduce;
    let traces = p.stage_dir("c-collect").join("traces.csv");
    if !p.done("c-collect") {
        std::fs::create_dir_all(p.fresh("c-collect")?)?;
        p.say("c-collect: the general model in every area (SPEC S7)");
        let n = r.collect_envs.unwrap_or(r.envs_per_area);
        drive(&p.envs(n), general, r.collect_steps, &traces)?;
        p.finish("c-collect", serde_json::json!({ "traces": traces }))?;
    }
    Ok(traces)
}

/// Stage d on stage c's `traces`: Table 3 and Figs. 5-8 on the paper's two terrains, the
/// K-kind classifier named on the recording with more.
fn analyse(p: &Pipeline, traces: &Path) -> anyhow::Result<()> {
    if p.done("d-analysis") {
        return Ok(());
    }
    let analysis = p.stage_dir("d-analysis");
    p.fresh("d-analysis")?;
    let windows = p
        .base
        .estimator
        .windows
        .iter()
        .map(std::string::ToString::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let mut cmd = Command::new(runtime::locate("estimator-proc")?);
    if p.paper_terrains() {
        p.say("d-analysis: Table 3, Figs. 5-8");
        cmd.arg("analyze").arg(traces).args(["--windows", &windows]);
    } else {
        p.say("d-analysis: the terrain kinds' classifier, named on the recording");
        cmd.arg("kinds").arg(traces);
    }
    let status = cmd
        .arg("--out")
        .arg(&analysis)
        .arg("--config")
        .arg(p.out.join(run_dir::CONFIG_TOML))
        .status()?;
    anyhow::ensure!(
        status.success(),
        "estimator-proc on {} failed",
        traces.display()
    );
    p.finish("d-analysis", serde_json::json!({ "windows": windows }))
}

/// Stage e: one specialist per role fine-tuned at once from stage b (or from new weights),
/// acting by switching.
fn train_specialists(p: &Pipeline, roles: &[Role]) -> anyhow::Result<()> {
    let r = &p.base.reproduce;
    let mut e = p.envs(r.envs_per_area);
    e.run.total_steps = r.finetune_steps;
    specialists_start(
        &mut e,
        roles,
        p.checkpoint("b-general", PolicySlot::General)?,
    );
    e.sim.acting = Acting::Switch;
    if !p.paper_terrains() {
        // SPEC S8 fits the estimator online; K kinds need the classifier named in stage d.
        p.estimate_with_stage_d(&mut e);
    }
    if let Some(scale) = r.finetune_roughness_scale {
        e.sim.terrain.roughness_scale = scale;
    }
    if r.specialist_candidates > 0 {
        e.ppo.milestone_every = p.milestone_every();
    }
    p.train("e-specialists", e)
}

/// Every model stage f evaluates, each with its policy file in `policies`: the general
/// model's (`general`), then each specialist of `selections` exported there.
fn models(
    p: &Pipeline,
    policies: &Path,
    general: PathBuf,
    roles: &[Role],
    selections: &[Selection],
) -> anyhow::Result<Vec<(&'static str, PathBuf)>> {
    let mut models = vec![("general", general)];
    for (role, s) in roles.iter().zip(selections) {
        let weights = policies.join(format!("{}.policy", role.model.to_lowercase()));
        p.export(s.checkpoint(), &weights)?;
        models.push((role.model, weights));
    }
    Ok(models)
}

/// Stage f: every model alone in every evaluation area, then switching between the chosen
/// specialists in each; its cells, kept from an earlier run when it finished.
fn evaluate(
    p: &Pipeline,
    models: &[(&'static str, PathBuf)],
    frozen: &BTreeMap<PolicySlot, PathBuf>,
    reading: Reading,
) -> anyhow::Result<Vec<Evaluated>> {
    if let Some(cells) = evaluated_before(p)? {
        return Ok(cells);
    }
    let eval = p.stage_dir("f-eval");
    std::fs::create_dir_all(p.fresh("f-eval")?)?;
    let mut cells = Vec::new();
    let areas = eval_areas(&p.kinds());
    for (name, weights) in models {
        for &area in &areas {
            cells.push(p.evaluate_policy(name, weights, area, p.test_courses(), &eval)?);
        }
    }
    for &area in &areas {
        cells.push(p.switching("switching", area, frozen, &eval, p.test_courses(), reading)?);
    }
    std::fs::write(eval.join(CELLS_JSON), serde_json::to_string(&cells)?)?;
    p.finish("f-eval", serde_json::json!({ "cells": cells.len() }))?;
    Ok(cells)
}

/// Stage e's learners, one per specialist, and what each starts from (SPEC S8): the general
/// model's weights at `reproduce.finetune-learning-rate`, or new weights at
/// `ppo.learning-rate` for the kinds of `reproduce.fresh-specialists`.
fn specialists_start(e: &mut Config, roles: &[Role], general: PathBuf) {
    let r = &e.reproduce;
    e.run.learners = roles.iter().map(|role| role.slot).collect();
    e.run.fresh = roles
        .iter()
        .filter(|role| r.fresh_specialists.contains(&role.kind))
        .map(|role| role.slot)
        .collect();
    e.run.init_learning_rate = r.finetune_learning_rate;
    e.run.init_from = Some(general);
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::Area;
    use common::config::AreaKind::{Flat, Gravel, Mixed, Slope};

    #[test]
    fn fresh_specialists_start_from_new_weights_the_others_from_the_general_model() {
        let kinds = [AreaKind::Flat, AreaKind::Rough, AreaKind::Sand];
        let mut e = Config::default();
        e.reproduce.finetune_learning_rate = Some(1e-4);
        e.reproduce.fresh_specialists = vec![AreaKind::Sand];
        let general = PathBuf::from("/out/b-general/checkpoints/last.ckpt");
        specialists_start(&mut e, &roles(&kinds), general.clone());
        assert_eq!(
            e.run.learners,
            [PolicySlot::Flat, PolicySlot::Rough, PolicySlot::Sand]
        );
        assert_eq!(e.run.warm_start(PolicySlot::Flat), Some(general.as_path()));
        assert_eq!(e.run.warm_start(PolicySlot::Rough), Some(general.as_path()));
        assert_eq!(e.run.warm_start(PolicySlot::Sand), None);
        assert_eq!(
            (e.run.init_learning_rate, e.ppo.learning_rate),
            (Some(1e-4), 3e-4),
            "fine-tuned slowly, the fresh one at PPO's own rate"
        );
        // The paper's pipeline: every specialist fine-tuned.
        e.reproduce.fresh_specialists.clear();
        specialists_start(&mut e, &roles(&kinds), general.clone());
        assert!(e.run.fresh.is_empty());
        assert_eq!(e.run.warm_start(PolicySlot::Sand), Some(general.as_path()));
    }

    #[test]
    fn switching_estimates_with_stage_d_s_classifier_for_the_world_s_kinds() {
        let mut p = Pipeline {
            base: Config::default(),
            out: PathBuf::from("/out"),
            quiet: true,
        };
        let mut cfg = Config::default();
        assert!(p.paper_terrains());
        p.estimate_with_stage_d(&mut cfg);
        assert_eq!(
            (
                cfg.estimator.model,
                cfg.estimator.kinds_model,
                cfg.estimator.refit_every
            ),
            (Some(PathBuf::from("/out/d-analysis/results.json")), None, 0)
        );
        p.base.sim.terrain.areas.push(Area {
            kind: AreaKind::Slope,
            x: [-9.0, -7.0],
            z: [0.0, 2.0],
        });
        assert_eq!(
            p.kinds(),
            [AreaKind::Flat, AreaKind::Rough, AreaKind::Slope]
        );
        let mut cfg = Config::default();
        p.estimate_with_stage_d(&mut cfg);
        assert_eq!(
            (cfg.estimator.model, cfg.estimator.kinds_model),
            (None, Some(PathBuf::from("/out/d-analysis/kinds.json")))
        );
        let b = p.envs(3);
        assert_eq!(
            [Flat, Slope, Gravel, Mixed].map(|a| b.sim.envs_in(a)),
            [3, 3, 0, 0]
        );
    }
}
