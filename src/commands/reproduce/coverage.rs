//! The reports' section on switching with live estimates (docs/EXPERIMENT.md E20): per
//! evaluation ground, how much of the switching model's driving had an estimate, acted on it,
//! how often it switched, and how soon it named each kind it crossed into.

use super::legs::Evaluated;
use super::stages::Pipeline;
use super::statistics::mean_ci;
use common::config::AreaKind;
use common::coverage::Coverage;

const HEADING: &str = "\n## Switching on live estimates (stage f)\n\n";

const DEFINITIONS: &str = "Counted from each env's first estimate on: the share of decision ticks with an estimate; of the ticks whose estimate had held for the dwell, the share acted by its specialist; changes of the acting slot per 100 m driven; and per kind crossed into, the crossings its specialist acted on before the robot left that ground, with the mean delay from the crossing.\n\n";

/// One seed's section: a row per ground the switching model drove.
pub(super) fn section(cells: &[Evaluated], dt: f64) -> String {
    if cells.iter().all(|e| e.coverage.is_none()) {
        return String::new();
    }
    let mut md = String::from(HEADING);
    md += DEFINITIONS;
    md += "| ground | ticks | with an estimate % | acted on % | switches per 100 m | crossings detected (mean delay) |\n|---|---:|---:|---:|---:|---|\n";
    for e in cells {
        let Some(c) = &e.coverage else { continue };
        md += &format!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {} |\n",
            e.area.name(),
            c.ticks,
            100.0 * c.with_estimate,
            100.0 * c.acting_on_estimate,
            c.switches_per_100m,
            c.crossings_text(dt).unwrap_or_else(|| "-".into())
        );
    }
    md
}

/// `mean ± ci` of `f` over the seeds' coverage of ground `area`.
fn over_seeds(covs: &[&Coverage], f: impl Fn(&Coverage) -> Option<f64>, digits: usize) -> String {
    let xs: Vec<f64> = covs.iter().filter_map(|c| f(c)).collect();
    if xs.is_empty() {
        return "-".into();
    }
    let (m, h) = mean_ci(&xs);
    format!("{m:.digits$} ± {h:.digits$}")
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
    md += "| ground | with an estimate % | acted on % | switches per 100 m | detected % and delay s, per kind |\n|---|---:|---:|---:|---|\n";
    for (i, e) in first.iter().enumerate() {
        if e.coverage.is_none() {
            continue;
        }
        let covs: Vec<&Coverage> = runs
            .iter()
            .filter_map(|(_, cells)| cells.get(i)?.coverage.as_ref())
            .collect();
        let kinds: Vec<String> = AreaKind::KINDS
            .into_iter()
            .filter(|k| covs.iter().any(|c| c.crossings.contains_key(k)))
            .map(|k| {
                let of = |c: &Coverage| c.crossings.get(&k).copied();
                let found = over_seeds(
                    &covs,
                    |c| of(c).map(|x| 100.0 * x.detected as f64 / x.crossings.max(1) as f64),
                    1,
                );
                let delay = over_seeds(
                    &covs,
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
        md += &format!(
            "| {} | {} | {} | {} | {} |\n",
            e.area.name(),
            over_seeds(&covs, |c| Some(100.0 * c.with_estimate), 1),
            over_seeds(&covs, |c| Some(100.0 * c.acting_on_estimate), 1),
            over_seeds(&covs, |c| Some(c.switches_per_100m), 1),
            if kinds.is_empty() {
                "-".into()
            } else {
                kinds.join("; ")
            }
        );
    }
    md
}
