//! The Markdown reports: one seed's `report.md` beside the paper's tables, and the report over
//! seeds with every number as mean ± 95 % CI.

use super::checks::{Check, SHAPE_CHECKS_HEADING, checks, shape_checks};
use super::coverage;
use super::evaluation::eval_areas;
use super::legs::{Cell, Evaluated};
use super::robustness;
use super::selection::{GENERAL, Selection, chosen_before, roles};
use super::stages::{Pipeline, Runs};
use super::statistics::mean_pm;
use super::tuning::Tuning;
use anyhow::Context;
use common::config::{AreaKind, PolicySlot};
use common::run_dir::{self, learner_dir};

/// One cell of the paper's Table 1: success %, mean reach time s, its std.
type PaperCell = (f64, f64, f64);

/// SPEC S8's Table 1 (50 trials per cell), per model: flat area, rough area.
const PAPER_TABLE_1: [(&str, [PaperCell; 2]); 3] = [
    ("general", [(100.0, 5.90, 2.54), (88.0, 10.51, 7.35)]),
    ("FTM", [(98.0, 5.47, 1.64), (76.0, 9.63, 4.29)]),
    ("RTM", [(98.0, 8.33, 5.92), (96.0, 8.96, 5.74)]),
];

/// SPEC S7's Table 3: window, accuracy %.
const PAPER_TABLE_3: [(u64, f64); 4] = [(10, 61.13), (20, 70.73), (40, 85.87), (70, 98.79)];

/// The heading of the specialists' choice, in a run's report and in the seeds report.
const SELECTION_HEADING: &str = "## Specialists chosen on validation courses (stage e)";

/// Table 1's cell `i` over seeds: success % and mean reach time, each mean ± CI.
fn table_1_cell(runs: &Runs, i: usize) -> (String, String) {
    let cells: Vec<Cell> = runs
        .iter()
        .filter_map(|(p, c)| {
            c.get(i)
                .map(|c| Cell::of(&c.legs, p.base.sim.decision_dt()))
        })
        .collect();
    let success: Vec<f64> = cells.iter().map(Cell::success_pct).collect();
    let reach: Vec<f64> = cells
        .iter()
        .filter(|c| c.successes > 0)
        .map(|c| c.mean_reach_s)
        .collect();
    (mean_pm(&success, 1), mean_pm(&reach, 2))
}

/// Each seed's claims about Table 1.
fn checks_per_seed(runs: &Runs) -> Vec<(u64, Vec<Check>)> {
    runs.iter()
        .map(|(p, cells)| {
            let r = &p.base.reproduce;
            (
                p.base.run.seed,
                checks(cells, p.base.sim.decision_dt(), (r.margin_pp, r.margin_s)),
            )
        })
        .collect()
}

/// The claim `key` over seeds: its success difference and reach-time advantage, each mean ±
/// CI, and each seed's verdict.
fn claim_over_seeds(per_seed: &[(u64, Vec<Check>)], key: &str) -> [String; 3] {
    let of_key: Vec<(u64, &Check)> = per_seed
        .iter()
        .filter_map(|(seed, cs)| cs.iter().find(|c| c.key == key).map(|c| (*seed, c)))
        .collect();
    let d: Vec<f64> = of_key.iter().map(|(_, c)| c.paired.difference.0).collect();
    let faster: Vec<f64> = of_key
        .iter()
        .filter(|(_, c)| c.paired.reached_by_both > 0)
        .map(|(_, c)| c.paired.faster.0)
        .collect();
    let verdicts: Vec<String> = of_key
        .iter()
        .map(|(seed, c)| {
            let versus = if c.claim == key {
                String::new()
            } else {
                format!(" ({})", c.claim)
            };
            format!("seed {seed}: {}{versus}", c.verdict)
        })
        .collect();
    [
        mean_pm(&d, 1),
        if faster.is_empty() {
            "-".into()
        } else {
            mean_pm(&faster, 2)
        },
        verdicts.join("; "),
    ]
}

/// Table 3 over seeds: each window's accuracy %, mean ± CI; with more than the paper's two
/// terrains, the K-kind classifier's macro accuracy.
fn table_3(runs: &Runs) -> anyhow::Result<std::collections::BTreeMap<u64, String>> {
    let mut by_window: std::collections::BTreeMap<u64, Vec<f64>> =
        std::collections::BTreeMap::default();
    for (p, _) in runs {
        let (file, field) = if p.paper_terrains() {
            ("results.json", "accuracy")
        } else {
            ("kinds.json", "macro_accuracy")
        };
        let path = p.stage_dir("d-analysis").join(file);
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&path)
                .with_context(|| format!("cannot read {}", path.display()))?,
        )?;
        for w in json["windows"].as_array().into_iter().flatten() {
            if let (Some(win), Some(acc)) = (w["window"].as_u64(), w[field].as_f64()) {
                by_window.entry(win).or_default().push(100.0 * acc);
            }
        }
    }
    Ok(by_window
        .into_iter()
        .map(|(w, accs)| (w, mean_pm(&accs, 2)))
        .collect())
}

/// The report over several seeds: every number as mean ± 95 % CI. With `beside` (another
/// pipeline's runs over the same seeds, `--beside`), each of its numbers is beside ours.
pub(super) fn seeds_report(runs: &Runs, beside: Option<&Runs>) -> anyhow::Result<String> {
    let mut md = seeds_heading(runs, beside);
    let Some((_, first)) = runs.first() else {
        return Ok(md);
    };
    for (i, Evaluated { model, area, .. }) in first.iter().enumerate() {
        let (success, reach) = table_1_cell(runs, i);
        let theirs = beside.map_or(String::new(), |b| {
            let (s, r) = table_1_cell(b, i);
            format!(" {s} | {r} |")
        });
        let paper = paper_cell(model, *area).map_or("-".into(), |(s, _, _)| format!("{s:.1}"));
        md += &format!(
            "| {model} | {} | {success} | {reach} |{theirs} {paper} |\n",
            area.name()
        );
    }
    md += &seeds_shape_checks(runs, beside);
    md += &coverage::seeds_section(runs);
    md += &robustness::seeds_section(runs, beside)?;
    md += &seeds_selection(runs)?;
    md += &coverage::seeds_tuning(runs)?;
    md += &seeds_table_3(runs, beside)?;
    Ok(md)
}

/// The header cells and the alignment row of `titles`, beside ours, when there is a
/// pipeline `beside`.
fn beside_columns(beside: Option<&Runs>, titles: &[&str], rule: &str) -> (String, String) {
    match beside {
        None => (String::new(), String::new()),
        Some(_) => (
            titles.iter().map(|t| format!(" beside: {t} |")).collect(),
            rule.repeat(titles.len()),
        ),
    }
}

/// The seeds report's title, what its numbers are, and the head of its Table 1.
fn seeds_heading(runs: &Runs, beside: Option<&Runs>) -> String {
    let (head, rule) = beside_columns(beside, &["success %", "reach s (mean)"], "---:|");
    format!(
        "# lavatube reproduce over {} seeds\n\n\
         Every number is the mean over seeds ± the half-width of its 95 % confidence interval \
         (Student's t); each seed's own report is in `seed-<seed>/report.md`.{}\n\n\
         ## Table 1\n\n\
         | model | area | success % | reach s (mean) |{head} paper: success % |\n\
         |---|---|---:|---:|{rule}---:|\n",
        runs.len(),
        beside
            .and_then(|b| b.first())
            .map_or(String::new(), |(p, _)| format!(
                " Columns headed \"beside\" are the pipeline in `{}` over the same seeds.",
                p.out.parent().unwrap_or(&p.out).display()
            )),
    )
}

/// The claims about Table 1 over seeds: each claim's differences as mean ± CI and each
/// seed's verdict.
fn seeds_shape_checks(runs: &Runs, beside: Option<&Runs>) -> String {
    let (head, _) = beside_columns(
        beside,
        &[
            "success difference, pp",
            "reach-time advantage, s",
            "holds, per seed",
        ],
        "",
    );
    let rule = beside.map_or("", |_| "---:|---:|---|");
    let mut md = format!(
        "\n{SHAPE_CHECKS_HEADING}\n\nPer seed on the legs both models drove (see each seed's report); the differences are means over seeds ± 95 % CI.\n\n| claim | success difference, pp | reach-time advantage, s | holds, per seed |{head}\n|---|---:|---:|---|{rule}\n"
    );
    let per_seed = checks_per_seed(runs);
    let theirs = beside.map(checks_per_seed);
    for key in per_seed
        .first()
        .map(|(_, c)| c)
        .into_iter()
        .flatten()
        .map(|c| &c.key)
    {
        let [d, faster, verdicts] = claim_over_seeds(&per_seed, key);
        let beside_cols = theirs.as_ref().map_or(String::new(), |t| {
            format!(" {} |", claim_over_seeds(t, key).join(" | "))
        });
        md += &format!("| {key} | {d} | {faster} | {verdicts} |{beside_cols}\n");
    }
    md
}

/// Each seed's chosen specialists, when its pipeline validated candidates; nothing when none
/// did.
fn seeds_selection(runs: &Runs) -> anyhow::Result<String> {
    let mut chosen = String::new();
    // None without `specialist-candidates`, whatever an earlier config left in `e-select`.
    for (p, _) in runs
        .iter()
        .filter(|(p, _)| p.base.reproduce.specialist_candidates > 0)
    {
        for s in chosen_before(p)?.into_iter().flatten() {
            chosen += &format!(
                "| {} | {} | {} |\n",
                p.base.run.seed, s.model, s.candidates[s.chosen].label
            );
        }
    }
    if chosen.is_empty() {
        return Ok(chosen);
    }
    Ok(format!(
        "\n{SELECTION_HEADING}\n\n| seed | model | chosen |\n|---:|---|---|\n{chosen}"
    ))
}

/// Table 3 over seeds beside the paper's accuracies.
fn seeds_table_3(runs: &Runs, beside: Option<&Runs>) -> anyhow::Result<String> {
    let (head, rule) = beside_columns(beside, &["accuracy %"], "---:|");
    let mut md = format!(
        "\n## Table 3: accuracy by window\n\n| window | accuracy % |{head} paper % |\n|---:|---:|{rule}---:|\n"
    );
    let theirs = beside.map(table_3).transpose()?;
    for (w, acc) in table_3(runs)? {
        let paper = PAPER_TABLE_3
            .iter()
            .find(|(pw, _)| *pw == w)
            .map_or("-".into(), |(_, a)| format!("{a:.2}"));
        let beside_col = theirs.as_ref().map_or(String::new(), |t| {
            format!(" {} |", t.get(&w).map_or("-", String::as_str))
        });
        md += &format!("| {w} | {acc} |{beside_col} {paper} |\n");
    }
    Ok(md)
}

/// Stage e's choice of specialists, when it validated candidates (`specialist-candidates`).
fn selection_table(selections: &[Selection], episodes: u64) -> String {
    if selections.iter().all(|s| s.candidates.len() < 2) {
        return String::new();
    }
    let mut md = format!(
        "\n{SELECTION_HEADING}\n\nEach specialist is the candidate that did best on its own terrain over validation courses (about {episodes} episodes each, seeds apart from the evaluation's): the general model it was fine-tuned from, or a checkpoint of its fine-tuning (`reproduce.specialist-candidates`). Best = the shortest reach time among those within `margin-pp` of the highest success rate, each measured on the legs all of them drove or reached (the table shows each candidate's own legs).\n\n| model | area | candidate | success % (episodes) | reach s, mean (std) | chosen |\n|---|---|---|---:|---:|:---:|\n"
    );
    for s in selections {
        for (k, c) in s.candidates.iter().enumerate() {
            let (success, reach) = c.cell.map_or(("-".into(), "-".into()), |cell| {
                (
                    format!("{:.1} ({})", cell.success_pct(), cell.episodes),
                    cell.reach(),
                )
            });
            md += &format!(
                "| {} | {} | {} | {success} | {reach} | {} |\n",
                s.model,
                s.area.name(),
                c.label,
                if k == s.chosen { "**yes**" } else { "" }
            );
        }
    }
    md
}

/// The paper's Table 1 cell for `model` in `area`, if the paper has one.
fn paper_cell(model: &str, area: AreaKind) -> Option<PaperCell> {
    PAPER_TABLE_1
        .iter()
        .find(|(m, _)| *m == model)
        .and_then(|(_, a)| a.get(area.code() as usize).copied())
}

/// One seed's `report.md`: Table 1 beside the paper's, the claims about it, the specialists'
/// choice, stage d's analysis, the learning curves and the maps.
pub(super) fn report(
    p: &Pipeline,
    cells: &[Evaluated],
    selections: &[Selection],
    tuning: Option<&Tuning>,
    worlds: Option<&[robustness::World]>,
) -> anyhow::Result<String> {
    let r = &p.base.reproduce;
    let mut md = table_1(p, cells);
    for s in selections {
        if s.candidates[s.chosen].label == GENERAL {
            md += &format!(
                "\n{} is the general model: no checkpoint of its fine-tuning drove {} ground better on the validation courses (stage e, below).\n",
                s.model,
                s.area.name()
            );
        }
    }
    md += &shape_checks(cells, p.base.sim.decision_dt(), (r.margin_pp, r.margin_s));
    md += &coverage::section(cells, p.base.sim.decision_dt());
    md += &worlds.map_or(String::new(), |w| {
        robustness::section(w, p.base.sim.decision_dt())
    });
    md += &selection_table(selections, r.validation_episodes);
    md += &tuning.map_or(String::new(), |t| coverage::tuning_section(t, p));
    md += &analysis(p)?;
    md += &learning_curves(p);
    md += &maps(p);
    Ok(md)
}

/// The report's title and Table 1: each cell's success rate and reach time beside the
/// paper's, on the ground each stage drove.
fn table_1(p: &Pipeline, cells: &[Evaluated]) -> String {
    let mut md = String::from("# lavatube reproduce\n\n");
    md += "The paper's pipeline (SPEC S6-S8) regenerated by `lavatube reproduce`; the resolved \
           config is `config.toml` beside this report.\n\n## Table 1: success rate and reach time\n\n";
    let r = &p.base.reproduce;
    let trained = p.base.sim.terrain.roughness_scale;
    md += &format!(
        "Ground: `roughness-scale` {trained} for stages a-d, {} for the fine-tuning (e) and {} \
         for this evaluation (f).\n\n",
        r.finetune_roughness_scale.unwrap_or(trained),
        r.eval_roughness_scale.unwrap_or(trained)
    );
    md += "| model | area | ours: success % (episodes) | ours: reach s, mean (std) | paper: success % | paper: reach s |\n|---|---|---:|---:|---:|---:|\n";
    for Evaluated {
        model, area, legs, ..
    } in cells
    {
        let cell = Cell::of(legs, p.base.sim.decision_dt());
        let (ps, pr) = paper_cell(model, *area).map_or(("-".into(), "-".into()), |(s, m, sd)| {
            (format!("{s:.1}"), format!("{m:.2} ({sd:.2})"))
        });
        md += &format!(
            "| {model} | {} | {:.1} ({}) | {} | {ps} | {pr} |\n",
            area.name(),
            cell.success_pct(),
            cell.episodes,
            cell.reach()
        );
    }
    md
}

/// Stage d's own report under a heading of this one: Table 3 and Figs. 5-8 on the paper's
/// terrains, the terrain kinds told apart with more.
fn analysis(p: &Pipeline) -> anyhow::Result<String> {
    let analysis = p.stage_dir("d-analysis");
    let (file, heading) = if p.paper_terrains() {
        ("results.md", "Table 3 and Figs. 5-8")
    } else {
        ("kinds.md", "Terrain kinds told apart")
    };
    let table3 = std::fs::read_to_string(analysis.join(file))
        .with_context(|| format!("cannot read {}", analysis.join(file).display()))?;
    let mut md = format!("\n## {heading} (stage d)\n\n");
    // Its own headings one level down, its figure links relative to this report.
    let table3 = table3
        .replace("](", "](d-analysis/")
        .replace("\n## ", "\n### ");
    md += table3.strip_prefix("# ").map_or(&table3[..], |t| {
        t.split_once('\n').map_or(t, |(_, rest)| rest)
    });
    Ok(md)
}

/// The learning curves of stages a and b and of every specialist of stage e that drew one.
fn learning_curves(p: &Pipeline) -> String {
    let mut md = String::from("\n## Learning curves\n\n");
    let specialists = roles(&p.kinds())
        .into_iter()
        .map(|r| ("e-specialists", r.slot));
    for (stage, slot) in [
        ("a-flat", PolicySlot::General),
        ("b-general", PolicySlot::General),
    ]
    .into_iter()
    .chain(specialists)
    {
        let png = learner_dir(&p.stage_dir(stage), slot).join(run_dir::CURVES_PNG);
        if png.is_file() {
            let rel = png.strip_prefix(&p.out).unwrap_or(&png);
            md += &format!("![{stage} {}]({})\n\n", slot.name(), rel.display());
        }
    }
    md
}

/// The maps of stage b's training and of switching on each evaluation ground, those drawn.
fn maps(p: &Pipeline) -> String {
    let mut md = String::from(
        "\n## Maps\n\nEach robot's last episodes: the general model's training (stage b), its path coloured by the estimator's class, then switching on each evaluation ground's first courses (stage f), coloured by the kind whose specialist acted (black: the general model, before the first estimate). Colours are the kinds' of every figure.\n\n",
    );
    let maps = std::iter::once(p.stage_dir("b-general")).chain(
        eval_areas(&p.kinds()).into_iter().map(|a| {
            p.stage_dir("f-eval")
                .join(format!("switching-{}-0", a.name()))
        }),
    );
    for dir in maps {
        let png = dir.join(run_dir::MAP_PNG);
        if png.is_file() {
            let rel = png.strip_prefix(&p.out).unwrap_or(&png);
            md += &format!("![map {}]({})\n\n", rel.display(), rel.display());
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::super::legs::Legs;
    use super::super::row_of;
    use super::*;
    use common::Config;

    #[test]
    fn the_seeds_report_lines_up_each_claim_across_seeds() {
        let dir = tempfile::tempdir().expect("tempdir");
        let legs = |ticks: u32| -> Legs { vec![vec![vec![Some(ticks); 50]]] };
        // Seed 1's best single model on rough ground is RTM, seed 2's FTM; switching drives
        // like RTM in both.
        let run = |seed: u64, ftm_rough: u32| {
            let out = dir.path().join(format!("seed-{seed}"));
            std::fs::create_dir_all(out.join("d-analysis")).expect("mkdir");
            std::fs::write(
                out.join("d-analysis/results.json"),
                r#"{"windows": [{"window": 70, "accuracy": 0.97}]}"#,
            )
            .expect("results");
            let mut base = Config::default();
            base.run.seed = seed;
            let mut cells = Vec::new();
            for area in [AreaKind::Flat, AreaKind::Rough, AreaKind::Mixed] {
                for (model, ticks) in [("general", 40), ("FTM", 40), ("RTM", 35), ("switching", 35)]
                {
                    let ticks = if model == "FTM" && area == AreaKind::Rough {
                        ftm_rough
                    } else {
                        ticks
                    };
                    cells.push(Evaluated {
                        model: model.into(),
                        area,
                        legs: legs(ticks),
                        coverage: None,
                    });
                }
            }
            let p = Pipeline {
                base,
                out,
                quiet: true,
            };
            (p, cells)
        };
        let md = seeds_report(&[run(1, 40), run(2, 34)], None).expect("report");
        let row = row_of(&md, "switching ≥ the best single model on rough");
        // Seed 1: like RTM, 0 s; seed 2: 0.1 s behind FTM on every leg; t(1) = 12.706.
        assert!(row.contains("| 0.0 ± 0.0 | -0.05 ± 0.64 |"), "{row}");
        assert!(
            row.ends_with(
                "| seed 1: yes (switching ≥ RTM on rough); seed 2: no (switching ≥ FTM on rough) |"
            ),
            "{row}"
        );
        assert!(row_of(&md, "RTM ≥ general on rough").ends_with("| seed 1: yes; seed 2: yes |"));
        assert!(row_of(&md, "70").contains("97.00"), "{md}");
        // Beside another pipeline over the same seeds, in which FTM drove rough ground as
        // the general model did: its numbers follow ours in each row.
        let theirs = [run(1, 40), run(2, 40)];
        let md = seeds_report(&[run(1, 40), run(2, 34)], Some(&theirs)).expect("report");
        let ftm = md
            .lines()
            .find(|l| l.starts_with("| FTM | rough |"))
            .expect("FTM row");
        assert!(
            ftm.ends_with("| 100.0 ± 0.0 | 4.00 ± 0.00 | 76.0 |"),
            "{ftm}"
        );
        let row = row_of(&md, "switching ≥ the best single model on rough");
        assert!(
            row.ends_with(
                "| seed 1: yes (switching ≥ RTM on rough); seed 2: yes (switching ≥ RTM on rough) |"
            ),
            "{row}"
        );
        assert_eq!(
            row_of(&md, "70"),
            "| 70 | 97.00 ± 0.00 | 97.00 ± 0.00 | 98.79 |"
        );
        assert!(
            md.contains(
                "| window | accuracy % | beside: accuracy % | paper % |\n|---:|---:|---:|---:|"
            ),
            "{md}"
        );
    }
}
