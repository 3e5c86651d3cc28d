//! The shape Table 1 should have (SPEC S8), checked leg by leg on one seed's cells: each
//! specialist at least as good as the general model on its terrain, switching at least as
//! good as the best single model in every area and better than the general model on the
//! mixed course. The claims follow the cells: FTM and RTM on the paper's terrains, one
//! specialist per kind on more.

use super::legs::{Cell, Evaluated};
use super::selection::kind_of;
use super::statistics::Paired;
use common::config::AreaKind;

/// The heading of the claims' table, in a run's report and in the seeds report.
pub(super) const SHAPE_CHECKS_HEADING: &str = "## Shape checks";

/// The claims about Table 1, each checked leg by leg: both models drove the same seeded
/// courses, so each claim compares them on the legs both drove (paired). A model "at least as
/// good" reached the target on more of those legs, or on as many and sooner on average over
/// the legs both reached. Each row gives the success-rate difference and the reach-time
/// advantage with their 95 % intervals over the paired legs. A model falls short when it is
/// worse by more than a margin (`reproduce.margin-pp`, `margin-s`) beyond the noise: a success
/// rate lower, or one not higher and a reach time longer. A claim that fails on the point
/// estimates reads "no" only when the model falls short, else "within margin". "Better than"
/// needs one measure better beyond the noise and the other not short: a success rate higher
/// beyond the noise with the reach time no longer than the margin beyond it, or a reach time
/// shorter beyond the noise with the success rate no lower than the margin beyond it; else it
/// reads "no" when the model falls short and "not shown" when it does not.
pub(super) fn shape_checks(cells: &[Evaluated], decision_dt: f64, margins: (f64, f64)) -> String {
    let (margin_pp, margin_s) = margins;
    let mut md = format!(
        "\n{SHAPE_CHECKS_HEADING}\n\nEach claim compares the two models on the legs both drove (same seed, env and leg of the evaluation course). \"At least as good\" reads \"no\" only when the first model falls short by more than {margin_pp} pp of success or {margin_s} s of reach time beyond the noise (`reproduce.margin-pp`, `margin-s`).\n\n| claim | paired legs | success % | reach s, legs both reached | success difference, pp (95 % CI) | reach-time advantage, s (95 % CI) | holds |\n|---|---:|---:|---:|---:|---:|:---:|\n",
    );
    for Check {
        claim,
        paired: c,
        verdict,
        ..
    } in checks(cells, decision_dt, margins)
    {
        let ((d, half), (faster, faster_half)) = (c.difference, c.faster);
        let (reach, advantage) = if c.reached_by_both > 0 {
            (
                format!("{:.2} vs {:.2}", c.reach[0], c.reach[1]),
                format!("{faster:+.2} ± {faster_half:.2}"),
            )
        } else {
            ("-".into(), "-".into())
        };
        md += &format!(
            "| {claim} | {} | {:.1} vs {:.1} | {reach} | {d:+.1} ± {half:.1} | {advantage} | {verdict} |\n",
            c.legs, c.success[0], c.success[1],
        );
    }
    md
}

/// One claim about Table 1, checked on one seed's cells.
pub(super) struct Check {
    /// E.g. "switching ≥ RTM on rough".
    pub(super) claim: String,
    /// The claim with the best single model unnamed ("switching ≥ the best single model on
    /// rough"), which lines seeds up when their best single models differ.
    pub(super) key: String,
    pub(super) paired: Paired,
    pub(super) verdict: &'static str,
}

/// The claims about Table 1 on `cells` (see [`shape_checks`]).
pub(super) fn checks(cells: &[Evaluated], decision_dt: f64, margins: (f64, f64)) -> Vec<Check> {
    let find =
        |model: &str, area: AreaKind| cells.iter().find(|c| c.model == model && c.area == area);
    // Models and areas in the cells' order: the general model, then the specialists.
    let mut specialists: Vec<(&str, AreaKind)> = Vec::new();
    let mut areas: Vec<AreaKind> = Vec::new();
    for c in cells {
        if let Some(kind) = kind_of(&c.model)
            && !specialists.iter().any(|(m, _)| *m == c.model)
        {
            specialists.push((&c.model, kind));
        }
        if !areas.contains(&c.area) {
            areas.push(c.area);
        }
    }
    let best_single = |area: AreaKind| {
        std::iter::once("general")
            .chain(specialists.iter().map(|(m, _)| *m))
            .filter_map(|m| find(m, area).map(|c| (m, Cell::of(&c.legs, decision_dt))))
            .max_by(|(_, a), (_, b)| rank(a).total_cmp(&rank(b)))
    };
    let mut claims: Vec<(&str, &str, AreaKind, bool, bool)> = specialists
        .iter()
        .map(|&(m, kind)| (m, "general", kind, false, false))
        .collect();
    for &area in &areas {
        if let Some((m, _)) = best_single(area) {
            claims.push(("switching", m, area, false, true));
        }
    }
    claims.push(("switching", "general", AreaKind::Mixed, true, false));
    let (margin_pp, margin_s) = margins;
    let mut out = Vec::new();
    for (a, b, area, strictly, best) in claims {
        let (Some(x), Some(y)) = (find(a, area), find(b, area)) else {
            continue;
        };
        let c = Paired::of(&x.legs, &y.legs, decision_dt);
        let ((d, half), (faster, faster_half)) = (c.difference, c.faster);
        // Short by more than the margins beyond the noise, on success and on reach time.
        let (short_success, short_reach) =
            (d + half < -margin_pp, faster + faster_half < -margin_s);
        let holds = if strictly {
            (d - half > 0.0 && !short_reach) || (faster - faster_half > 0.0 && !short_success)
        } else {
            d > 0.0 || (d == 0.0 && faster >= 0.0)
        };
        let short = short_success || (d - half <= 0.0 && short_reach);
        let verdict = match (holds, short, strictly) {
            (true, _, _) => "yes",
            (false, true, _) => "no",
            (false, false, false) => "within margin",
            (false, false, true) => "not shown",
        };
        let relation = if strictly { "better than" } else { "≥" };
        let claim = |b: &str| format!("{a} {relation} {b} on {}", area.name());
        out.push(Check {
            claim: claim(b),
            key: if best {
                claim("the best single model")
            } else {
                claim(b)
            },
            paired: c,
            verdict,
        });
    }
    out
}

/// Orders cells by success rate, then by shorter mean reach time.
fn rank(c: &Cell) -> f64 {
    c.success_pct() * 1e3 - c.mean_reach_s.min(999.0)
}

#[cfg(test)]
mod tests {
    use super::super::legs::Legs;
    use super::super::row_of;
    use super::*;

    #[test]
    fn shape_checks_compare_the_models_leg_by_leg() {
        // One part, one env, `n` legs: leg i reached in `ticks(i)` ticks, or failed.
        let legs = |n: usize, ticks: &dyn Fn(usize) -> Option<u32>| -> Legs {
            vec![vec![(0..n).map(ticks).collect()]]
        };
        let eval = |model: &str, area: AreaKind, legs: Legs| Evaluated {
            model: model.into(),
            area,
            legs,
            coverage: None,
        };
        let base = legs(100, &|i| (i % 10 != 0).then_some(30 + (i % 7) as u32));
        let mut cells = Vec::new();
        for area in [AreaKind::Flat, AreaKind::Rough, AreaKind::Mixed] {
            for model in ["general", "FTM", "RTM", "switching"] {
                cells.push(eval(model, area, base.clone()));
            }
        }
        let checks = |cells: &[Evaluated]| shape_checks(cells, 0.1, (0.0, 0.0));
        let md = checks(&cells);
        // Identical legs (mean reach 32.94 ticks): at least as good, and not better.
        assert!(
            row_of(&md, "FTM ≥ general on flat").ends_with(
                "| 100 | 90.0 vs 90.0 | 3.29 vs 3.29 | +0.0 ± 0.0 | +0.00 ± 0.00 | yes |"
            ),
            "{md}"
        );
        assert!(row_of(&md, "switching better than general on mixed").ends_with("| not shown |"));
        // Ties go to the last of the single models, RTM. One tick slower on every leg
        // reached: worse beyond the noise.
        cells[3] = eval(
            "switching",
            AreaKind::Flat,
            legs(100, &|i| (i % 10 != 0).then_some(31 + (i % 7) as u32)),
        );
        assert!(
            row_of(&checks(&cells), "switching ≥ RTM on flat")
                .ends_with("| +0.0 ± 0.0 | -0.10 ± 0.00 | no |")
        );
        // Inside a 0.2 s margin it is not a "no".
        assert!(
            row_of(
                &shape_checks(&cells, 0.1, (1.0, 0.2)),
                "switching ≥ RTM on flat"
            )
            .ends_with("| within margin |")
        );
        // One leg of 100 lost: -1 pp, sd 10, so ± 1.98 (t(99)): within the noise.
        cells[7] = eval(
            "switching",
            AreaKind::Rough,
            legs(100, &|i| {
                (i % 10 != 0 && i != 1).then_some(30 + (i % 7) as u32)
            }),
        );
        assert!(
            row_of(&checks(&cells), "switching ≥ RTM on rough")
                .ends_with("| -1.0 ± 2.0 | +0.00 ± 0.00 | within margin |")
        );
        // Ten more legs reached on the mixed course: +10 pp ± 6.0, better beyond the noise.
        cells[11] = eval(
            "switching",
            AreaKind::Mixed,
            legs(100, &|i| Some(30 + (i % 7) as u32)),
        );
        assert!(
            row_of(&checks(&cells), "switching better than general on mixed")
                .ends_with("| +10.0 ± 6.0 | +0.00 ± 0.00 | yes |")
        );
    }

    #[test]
    fn every_kind_s_specialist_and_area_gets_its_claims() {
        let legs: Legs = vec![vec![vec![Some(30); 20]]];
        let mut cells = Vec::new();
        for model in ["general", "FTM", "RTM", "STM", "GTM", "switching"] {
            for area in [
                AreaKind::Flat,
                AreaKind::Rough,
                AreaKind::Slope,
                AreaKind::Gravel,
                AreaKind::Mixed,
            ] {
                cells.push(Evaluated {
                    model: model.into(),
                    area,
                    legs: legs.clone(),
                    coverage: None,
                });
            }
        }
        let keys: Vec<String> = checks(&cells, 0.1, (1.0, 0.05))
            .into_iter()
            .map(|c| c.key)
            .collect();
        assert_eq!(
            keys,
            [
                "FTM ≥ general on flat",
                "RTM ≥ general on rough",
                "STM ≥ general on slope",
                "GTM ≥ general on gravel",
                "switching ≥ the best single model on flat",
                "switching ≥ the best single model on rough",
                "switching ≥ the best single model on slope",
                "switching ≥ the best single model on gravel",
                "switching ≥ the best single model on mixed",
                "switching better than general on mixed",
            ]
        );
    }

    #[test]
    fn better_means_one_measure_better_and_the_other_not_short() {
        let legs = |ticks: &dyn Fn(usize) -> Option<u32>| -> Legs {
            vec![vec![(0..200).map(ticks).collect()]]
        };
        let eval = |model: &str, legs: Legs| Evaluated {
            model: model.into(),
            area: AreaKind::Mixed,
            legs,
            coverage: None,
        };
        let general = eval("general", legs(&|i| Some(40 + (i % 5) as u32)));
        // Six legs of 200 lost (-3.0 pp, sd 17.1, ± 2.4) but 0.3 s sooner on the rest.
        let faster = eval(
            "switching",
            legs(&|i| (i >= 6).then_some(37 + (i % 5) as u32)),
        );
        let row = |margins| {
            row_of(
                &shape_checks(&[general.clone(), faster.clone()], 0.1, margins),
                "switching better than general on mixed",
            )
        };
        // Faster beyond the noise, and the success loss not beyond a 1 pp margin.
        assert!(row((1.0, 0.05)).ends_with("| -3.0 ± 2.4 | +0.30 ± 0.00 | yes |"));
        // Without a margin, the loss is beyond the noise: short.
        assert!(row((0.0, 0.05)).ends_with("| no |"));
    }
}
