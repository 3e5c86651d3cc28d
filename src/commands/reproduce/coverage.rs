//! The reports' section on switching with live estimates (docs/EXPERIMENT.md E20): per
//! evaluation ground, how much of the switching model's driving had an estimate, acted on it,
//! how often it switched, and how soon it named each kind it crossed into; and stage e's
//! choice of the online window and dwell it read the ground with.

use super::legs::Evaluated;
use super::stages::Pipeline;
use super::statistics::mean_pm;
use super::tuning::{Tried, Tuning, tuned_before};
use common::config::AreaKind;
use common::coverage::Coverage;

const HEADING: &str = "\n## Switching on live estimates (stage f)\n\n";

const DEFINITIONS: &str = "Counted from each env's first estimate on: the share of decision ticks with an estimate, and of those the share naming the ground under the robot; of the ticks whose estimate had held for the dwell, the share acted by its specialist; changes of the acting slot per 100 m driven; and per kind crossed into, the crossings its specialist acted on before the robot left that ground, with the mean delay from the crossing.\n\n";

/// One seed's section: a row per ground the switching model drove.
pub(super) fn section(cells: &[Evaluated], dt: f64) -> String {
    if cells.iter().all(|e| e.coverage.is_none()) {
        return String::new();
    }
    let mut md = String::from(HEADING);
    md += DEFINITIONS;
    md += &format!("| ground | ticks | {COLUMNS} |\n|---|---:|{COLUMN_RULES}\n");
    for e in cells {
        let Some(c) = &e.coverage else { continue };
        md += &format!(
            "| {} | {} | {} |\n",
            e.area.name(),
            c.ticks,
            cells_of(c, dt)
        );
    }
    md
}

/// The coverage columns of every table here, and their alignment row.
const COLUMNS: &str =
    "with an estimate % | right % | acted on % | switches per 100 m | crossings detected";
const COLUMN_RULES: &str = "---:|---:|---:|---:|---|";

/// One run's [`COLUMNS`]: the crossings as detected of crossed, after the mean delay.
fn cells_of(c: &Coverage, dt: f64) -> String {
    format!(
        "{:.1} | {} | {:.1} | {:.1} | {}",
        100.0 * c.with_estimate,
        c.right_pct(),
        100.0 * c.acting_on_estimate,
        c.switches_per_100m,
        c.crossings_text(dt).unwrap_or_else(|| "-".into())
    )
}

/// The seeds' [`COLUMNS`] as mean ± 95 % CI: the crossings as the share detected and the
/// delay in seconds, per kind.
fn cells_over_seeds(covs: &[&Coverage], dt: f64) -> String {
    format!(
        "{} | {} | {} | {} | {}",
        over_seeds(covs, |c| Some(100.0 * c.with_estimate), 1),
        over_seeds(covs, |c| c.estimate_right.map(|r| 100.0 * r), 1),
        over_seeds(covs, |c| Some(100.0 * c.acting_on_estimate), 1),
        over_seeds(covs, |c| Some(c.switches_per_100m), 1),
        crossings_over_seeds(covs, dt)
    )
}

/// `mean ± ci` of `f` over the seeds' records `xs` (those it has a value for), `-` when none
/// has one.
fn over_seeds<T>(xs: &[T], f: impl Fn(&T) -> Option<f64>, digits: usize) -> String {
    let xs: Vec<f64> = xs.iter().filter_map(f).collect();
    mean_pm(&xs, digits)
}

/// The section over seeds: every number as mean ± 95 % CI, the delay per kind in seconds.
pub(super) fn seeds_section(runs: &[(Pipeline, Vec<Evaluated>)]) -> String {
    let Some((p, first)) = runs
        .first()
        .filter(|(_, c)| c.iter().any(|e| e.coverage.is_some()))
    else {
        return String::new();
    };
    let dt = p.base.sim.decision_dt();
    let mut md = String::from(HEADING);
    md += DEFINITIONS;
    md += &format!("| ground | {COLUMNS} |\n|---|{COLUMN_RULES}\n");
    for (i, e) in first.iter().enumerate() {
        if e.coverage.is_none() {
            continue;
        }
        let covs: Vec<&Coverage> = runs
            .iter()
            .filter_map(|(_, cells)| cells.get(i)?.coverage.as_ref())
            .collect();
        md += &format!("| {} | {} |\n", e.area.name(), cells_over_seeds(&covs, dt));
    }
    md
}

/// Per kind crossed into, over the seeds' `covs`: the share detected and the mean delay in
/// seconds at decision step `dt`; `-` when no robot crossed.
fn crossings_over_seeds(covs: &[&Coverage], dt: f64) -> String {
    let kinds: Vec<String> = AreaKind::KINDS
        .into_iter()
        .filter(|k| covs.iter().any(|c| c.crossings.contains_key(k)))
        .map(|k| {
            let of = |c: &Coverage| c.crossings.get(&k).copied();
            let found = over_seeds(
                covs,
                |c| of(c).map(|x| 100.0 * x.detected as f64 / x.crossings.max(1) as f64),
                1,
            );
            let delay = over_seeds(
                covs,
                |c| {
                    of(c)
                        .filter(|x| x.detected > 0)
                        .map(|x| x.mean_delay_ticks * dt)
                },
                2,
            );
            format!("{} {found} %, {delay} s", k.name())
        })
        .collect();
    if kinds.is_empty() {
        "-".into()
    } else {
        kinds.join("; ")
    }
}

const TUNING_HEADING: &str =
    "\n## Online window and dwell chosen on validation courses (stage e)\n\n";

/// What the tuning section's numbers are, for validation courses of about `episodes` each.
fn tuning_definitions(episodes: u64) -> String {
    format!(
        "Switching between the chosen specialists drove the mixed validation courses (about {episodes} episodes each, seeds apart from the evaluation's) once per online window × dwell (`reproduce.switch-windows`, `reproduce.switch-dwells`, EXPERIMENT E21). The one stage f uses is chosen as the specialists are: the shortest reach time among those within `margin-pp` of the highest success rate. Right % is the share of ticks with an estimate that name the ground under the robot (accuracy); the detection delay runs from crossing into a part of the course to its specialist acting.\n\n"
    )
}

/// One seed's stage e-switch: a row per reading tried.
pub(super) fn tuning_section(t: &Tuning, p: &Pipeline) -> String {
    let dt = p.base.sim.decision_dt();
    let mut md = String::from(TUNING_HEADING);
    md += &tuning_definitions(p.base.reproduce.validation_episodes);
    md += &format!(
        "| window, ticks | dwell, ticks | success % (episodes) | reach s, mean (std) | {COLUMNS} | chosen |\n|---:|---:|---:|---:|{COLUMN_RULES}:---:|\n"
    );
    for (k, x) in t.tried.iter().enumerate() {
        md += &format!(
            "| {} | {} | {:.1} ({}) | {} | {} | {} |\n",
            x.reading.window,
            x.reading.dwell,
            x.cell.success_pct(),
            x.cell.episodes,
            x.cell.reach(),
            cells_of(&x.coverage, dt),
            if k == t.chosen { "**yes**" } else { "" }
        );
    }
    md
}

/// Stage e-switch over seeds: each reading's numbers as mean ± 95 % CI and the seeds that
/// chose it; nothing when no seed tuned.
pub(super) fn seeds_tuning(runs: &[(Pipeline, Vec<Evaluated>)]) -> anyhow::Result<String> {
    let mut tunings = Vec::new();
    for (p, _) in runs {
        if let Some(t) = tuned_before(p)? {
            tunings.push((p.base.run.seed, t));
        }
    }
    let Some(((_, first), (p, _))) = tunings.first().zip(runs.first()) else {
        return Ok(String::new());
    };
    let dt = p.base.sim.decision_dt();
    let mut md = String::from(TUNING_HEADING);
    md += &tuning_definitions(p.base.reproduce.validation_episodes);
    md += &format!(
        "| window, ticks | dwell, ticks | success % | reach s (mean) | {COLUMNS} | chosen in seeds |\n|---:|---:|---:|---:|{COLUMN_RULES}---|\n"
    );
    for x in &first.tried {
        let tried: Vec<&Tried> = tunings
            .iter()
            .filter_map(|(_, t)| t.tried.iter().find(|y| y.reading == x.reading))
            .collect();
        let covs: Vec<&Coverage> = tried.iter().map(|y| &y.coverage).collect();
        let chosen: Vec<String> = tunings
            .iter()
            .filter(|(_, t)| t.reading() == x.reading)
            .map(|(seed, _)| seed.to_string())
            .collect();
        md += &format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            x.reading.window,
            x.reading.dwell,
            over_seeds(&tried, |y| Some(y.cell.success_pct()), 1),
            over_seeds(
                &tried,
                |y| (y.cell.successes > 0).then_some(y.cell.mean_reach_s),
                2
            ),
            cells_over_seeds(&covs, dt),
            if chosen.is_empty() {
                "-".into()
            } else {
                chosen.join(", ")
            }
        );
    }
    Ok(md)
}
