//! Stage f on the robustness worlds (`reproduce.robustness-worlds`): the general model and
//! switching between the chosen specialists drive the mixed course in each world of the file,
//! laid over the pipeline's config without its `[sim.randomize]`, so a pipeline trained under
//! randomization and one trained without it meet the same worlds; and the report's section
//! on them, per seed and over seeds (with `--beside`, the other pipeline's beside).

use super::super::evaluate::worlds;
use super::legs::{Cell, Evaluated};
use super::stages::{Pipeline, Runs};
use super::statistics::mean_pm;
use super::tuning::Reading;
use common::config::{AreaKind, PolicySlot, RandomizeConfig};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const STAGE: &str = "f-robustness";
const CELLS_JSON: &str = "cells.json";

/// One world's cells: the general model's, then switching's.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct World {
    pub(super) name: String,
    pub(super) cells: Vec<Evaluated>,
}

/// The worlds' cells, kept from an earlier run when it finished; `None` without
/// `reproduce.robustness-worlds`.
pub(super) fn drive(
    p: &Pipeline,
    general: &Path,
    frozen: &BTreeMap<PolicySlot, PathBuf>,
    reading: Reading,
) -> anyhow::Result<Option<Vec<World>>> {
    let Some(file) = &p.base.reproduce.robustness_worlds else {
        return Ok(None);
    };
    if let Some(kept) = kept(p)? {
        return Ok(Some(kept));
    }
    let mut nominal = p.base.clone();
    nominal.sim.randomize = RandomizeConfig::default();
    let dir = p.fresh(STAGE)?;
    let mut out = Vec::new();
    for w in worlds::read(file, &nominal)? {
        let q = Pipeline {
            base: w.cfg,
            out: p.out.clone(),
            quiet: p.quiet,
        };
        let eval = dir.join(&w.name);
        std::fs::create_dir_all(&eval)?;
        let courses = q.robustness_courses(STAGE);
        let area = AreaKind::Mixed;
        let cells = vec![
            q.evaluate_policy("general", general, area, courses, &eval)?,
            q.switching("switching", area, frozen, &eval, courses, reading)?,
        ];
        out.push(World {
            name: w.name,
            cells,
        });
    }
    std::fs::write(dir.join(CELLS_JSON), serde_json::to_string(&out)?)?;
    p.finish(STAGE, serde_json::json!({ "worlds": out.len() }))?;
    Ok(Some(out))
}

/// The worlds' cells of `p`'s finished stage, if any.
pub(super) fn kept(p: &Pipeline) -> anyhow::Result<Option<Vec<World>>> {
    p.kept(STAGE, CELLS_JSON, "the robustness worlds' legs")
}

const HEADING: &str = "## Robustness worlds (stage f)\n\n\
    The general model and switching on the mixed course in each world of \
    `reproduce.robustness-worlds`, laid over this pipeline's config without its \
    `[sim.randomize]`: success % and mean reach time, s.\n\n";

/// One seed's section: a line per world.
pub(super) fn section(worlds: &[World], dt: f64) -> String {
    let mut md = format!(
        "\n{HEADING}| world | general: success % | reach s | switching: success % | reach s |\n\
         |---|---:|---:|---:|---:|\n"
    );
    for w in worlds {
        md += &format!("| {} |", w.name);
        for c in &w.cells {
            let cell = Cell::of(&c.legs, dt);
            md += &format!(" {:.1} | {} |", cell.success_pct(), reach(&cell));
        }
        md += "\n";
    }
    md
}

fn reach(c: &Cell) -> String {
    if c.successes == 0 {
        "-".into()
    } else {
        format!("{:.2}", c.mean_reach_s)
    }
}

/// Success % of the general model and of switching in each world of each run, by world name;
/// the runs' worlds read once each.
fn success_by_world(runs: &Runs) -> anyhow::Result<Vec<(String, [Vec<f64>; 2])>> {
    let mut out: Vec<(String, [Vec<f64>; 2])> = Vec::new();
    for (p, _) in runs {
        let dt = p.base.sim.decision_dt();
        for w in kept(p)?.unwrap_or_default() {
            let at = match out.iter().position(|(name, _)| *name == w.name) {
                Some(at) => at,
                None => {
                    out.push((w.name.clone(), Default::default()));
                    out.len() - 1
                }
            };
            for (xs, c) in out[at].1.iter_mut().zip(&w.cells) {
                xs.push(Cell::of(&c.legs, dt).success_pct());
            }
        }
    }
    Ok(out)
}

/// The section over seeds: per world, each model's success % as mean ± 95 % CI, and the
/// pipeline `beside`'s in the same worlds beside it; empty when no run drove the worlds.
pub(super) fn seeds_section(runs: &Runs, beside: Option<&Runs>) -> anyhow::Result<String> {
    let ours = success_by_world(runs)?;
    if ours.is_empty() {
        return Ok(String::new());
    }
    let theirs = beside.map(success_by_world).transpose()?;
    let (head, rule) = match theirs {
        Some(_) => (" beside: general | beside: switching |", "---:|---:|"),
        None => ("", ""),
    };
    let mut md = format!(
        "\n{HEADING}| world | general: success % | switching: success % |{head}\n\
         |---|---:|---:|{rule}\n"
    );
    for (name, models) in &ours {
        md += &format!("| {name} |");
        let mut cells: Vec<&[f64]> = models.iter().map(Vec::as_slice).collect();
        if let Some(t) = &theirs {
            let same = t.iter().find(|(n, _)| n == name).map(|(_, m)| m);
            cells.extend((0..2).map(|i| same.map_or(&[][..], |m| m[i].as_slice())));
        }
        for xs in cells {
            md += &format!(" {} |", mean_pm(xs, 1));
        }
        md += "\n";
    }
    Ok(md)
}
