//! The stages in their order (a–g, see the command's docs), each resumed or run afresh.

use super::evaluation::EVAL_AREAS;
use super::legs::Evaluated;
use super::report::report;
use super::selection::specialists;
use crate::runtime;
use anyhow::Context;
use common::config::{Acting, PolicySlot};
use common::{Config, run_dir};
use std::path::PathBuf;
use std::process::Command;

/// The pipeline's directories and binaries.
pub(super) struct Pipeline {
    pub(super) base: Config,
    pub(super) out: PathBuf,
    pub(super) quiet: bool,
}

impl Pipeline {
    /// The base config with `flat` + `rough` envs.
    fn envs(&self, flat: usize, rough: usize) -> Config {
        let mut c = self.base.clone();
        c.sim.flat_envs = flat;
        c.sim.rough_envs = rough;
        c.sim.mixed_envs = 0;
        c
    }
}

/// Where stage f keeps its cells.
const CELLS_JSON: &str = "cells.json";

/// Stage f's cells, if it finished.
pub(super) fn evaluated_before(p: &Pipeline) -> anyhow::Result<Option<Vec<Evaluated>>> {
    if !p.done("f-eval") {
        return Ok(None);
    }
    let eval = p.stage_dir("f-eval");
    let path = eval.join(CELLS_JSON);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).map(Some).with_context(|| {
        format!(
            "{} is not stage f's legs (an older lavatube's?): remove {} to evaluate again",
            path.display(),
            eval.display()
        )
    })
}

/// One seed's pipeline, stages a–g in `p.out`.
pub(super) fn run(p: &Pipeline) -> anyhow::Result<Vec<Evaluated>> {
    let base = &p.base;
    let out = &p.out;
    let r = &base.reproduce;
    std::fs::write(out.join(run_dir::CONFIG_TOML), base.to_toml())?;

    let mut a = p.envs(r.flat_envs, 0);
    a.run.total_steps = r.flat_steps;
    p.train("a-flat", a)?;

    let mut b = p.envs(r.envs_per_area, r.envs_per_area);
    b.run.total_steps = r.general_steps;
    b.run.init_from = Some(p.checkpoint("a-flat", PolicySlot::General)?);
    p.train("b-general", b)?;

    let policies = p.stage_dir("policies");
    std::fs::create_dir_all(&policies)?;
    let general = policies.join("general.policy");
    p.export(&p.checkpoint("b-general", PolicySlot::General)?, &general)?;

    let traces = p.stage_dir("c-collect").join("traces.csv");
    if !p.done("c-collect") {
        std::fs::create_dir_all(p.fresh("c-collect")?)?;
        p.say("c-collect: the general model in both areas (SPEC S7)");
        let n = r.collect_envs.unwrap_or(r.envs_per_area);
        p.drive(&p.envs(n, n), &general, r.collect_steps, &traces)?;
        p.finish("c-collect", serde_json::json!({ "traces": traces }))?;
    }

    let analysis = p.stage_dir("d-analysis");
    if !p.done("d-analysis") {
        p.fresh("d-analysis")?;
        p.say("d-analysis: Table 3, Figs. 5-8");
        let windows = base
            .estimator
            .windows
            .iter()
            .map(std::string::ToString::to_string)
            .collect::<Vec<_>>()
            .join(",");
        let status = Command::new(runtime::locate("estimator-proc")?)
            .arg("analyze")
            .arg(&traces)
            .args(["--windows", &windows, "--out"])
            .arg(&analysis)
            .arg("--config")
            .arg(out.join(run_dir::CONFIG_TOML))
            .status()?;
        anyhow::ensure!(status.success(), "estimator-proc analyze failed");
        p.finish("d-analysis", serde_json::json!({ "windows": windows }))?;
    }

    let mut e = p.envs(r.envs_per_area, r.envs_per_area);
    e.run.total_steps = r.finetune_steps;
    e.run.learners = vec![PolicySlot::Flat, PolicySlot::Rough];
    e.run.init_from = Some(p.checkpoint("b-general", PolicySlot::General)?);
    e.sim.acting = Acting::Switch;
    if let Some(scale) = r.finetune_roughness_scale {
        e.sim.terrain.roughness_scale = scale;
    }
    if let Some(lr) = r.finetune_learning_rate {
        e.ppo.learning_rate = lr;
    }
    if r.specialist_candidates > 0 {
        e.ppo.milestone_every = p.milestone_every();
    }
    p.train("e-specialists", e)?;
    let selections = specialists(p)?;
    let models = [
        ("general", general),
        ("FTM", policies.join("ftm.policy")),
        ("RTM", policies.join("rtm.policy")),
    ];
    for ((_, weights), s) in models[1..].iter().zip(&selections) {
        p.export(s.checkpoint(), weights)?;
    }

    let eval = p.stage_dir("f-eval");
    let cells_path = eval.join(CELLS_JSON);
    let cells: Vec<Evaluated> = if let Some(cells) = evaluated_before(p)? {
        cells
    } else {
        std::fs::create_dir_all(p.fresh("f-eval")?)?;
        let mut cells = Vec::new();
        for (name, weights) in &models {
            for area in EVAL_AREAS {
                cells.push(p.evaluate_policy(name, weights, area, p.test_courses(), &eval)?);
            }
        }
        let frozen = [PolicySlot::Flat, PolicySlot::Rough]
            .into_iter()
            .zip(selections.iter().map(|s| s.checkpoint().to_path_buf()))
            .collect();
        for area in EVAL_AREAS {
            cells.push(p.switching(area, &frozen, &eval)?);
        }
        std::fs::write(&cells_path, serde_json::to_string(&cells)?)?;
        p.finish("f-eval", serde_json::json!({ "cells": cells.len() }))?;
        cells
    };

    let report = report(p, &cells, &selections)?;
    let path = out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    println!("report: {}", path.display());
    Ok(cells)
}
