//! What `lavatube evaluate` found: per world and policy, the success rate and the reach time
//! with their 95 % intervals over the episodes, as a Markdown table, JSON and a chart.

use super::super::reproduce::legs::{Legs, reach_times};
use super::super::reproduce::statistics::{interval, mean_ci};
use anyhow::Context;
use common::bars::{Series, grouped_bars};
use std::path::Path;

/// One policy in one world.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Row {
    pub world: String,
    pub policy: String,
    pub episodes: usize,
    /// Success %, and the half-width of its 95 % interval (Student's t over the episodes'
    /// 0 or 100).
    pub success_pct: (f64, f64),
    /// Mean reach time of the successful episodes, seconds, and its 95 % half-width.
    pub reach_s: (f64, f64),
}

impl Row {
    /// The row of `policy` in `world` from the legs it drove, at `decision_dt` s per tick.
    pub fn of(world: &str, policy: &str, legs: &Legs, decision_dt: f64) -> Self {
        let (episodes, reach) = reach_times(legs, decision_dt);
        // Each leg's success, 100 or 0: its mean is the success rate.
        let mut success = vec![0.0; episodes];
        success[..reach.len()].fill(100.0);
        Self {
            world: world.into(),
            policy: policy.into(),
            episodes,
            success_pct: mean_ci(&success),
            reach_s: if reach.is_empty() {
                (f64::NAN, f64::NAN)
            } else {
                mean_ci(&reach)
            },
        }
    }

    /// The progress line of the row.
    pub fn line(&self) -> String {
        format!(
            "{}: {}: {}% of {} episodes, reach s {}",
            self.world,
            self.policy,
            interval(self.success_pct, 1),
            self.episodes,
            interval(self.reach_s, 2)
        )
    }
}

/// The row of `policy` in `world`, if it drove there.
fn find<'a>(rows: &'a [Row], world: &str, policy: &str) -> Option<&'a Row> {
    rows.iter().find(|r| r.world == world && r.policy == policy)
}

/// The Markdown table: a line per world, success % and reach s per policy.
pub fn markdown(rows: &[Row], worlds: &[String], policies: &[String]) -> String {
    let mut out = String::from("| world |");
    for p in policies {
        out += &format!(" {p} success % | {p} reach s |");
    }
    out += "\n|---|";
    out += &"---:|---:|".repeat(policies.len());
    for w in worlds {
        out += &format!("\n| {w} |");
        for p in policies {
            out += &find(rows, w, p).map_or(" | |".into(), |r| {
                format!(
                    " {} | {} |",
                    interval(r.success_pct, 1),
                    interval(r.reach_s, 2)
                )
            });
        }
    }
    out + "\n"
}

/// Writes `evaluation.md` (a heading line `title`, then the table), `evaluation.json` and
/// `evaluation.png` (success per world and policy) to `out`.
pub fn write(
    out: &Path,
    title: &str,
    rows: &[Row],
    worlds: &[String],
    policies: &[String],
) -> anyhow::Result<()> {
    let md = out.join("evaluation.md");
    let text = format!("{title}\n\n{}", markdown(rows, worlds, policies));
    std::fs::write(&md, text).with_context(|| format!("cannot write {}", md.display()))?;
    let json = out.join("evaluation.json");
    std::fs::write(&json, serde_json::to_string_pretty(rows)?)
        .with_context(|| format!("cannot write {}", json.display()))?;
    let series: Vec<Series> = policies
        .iter()
        .map(|p| Series {
            label: p.clone(),
            values: worlds
                .iter()
                .map(|w| find(rows, w, p).map_or((0.0, f64::NAN), |r| r.success_pct))
                .collect(),
        })
        .collect();
    let png = out.join("evaluation.png");
    grouped_bars(&png, title, "success % (95 % CI)", worlds, &series, 100.0)
        .map_err(|e| anyhow::anyhow!("chart {}: {e}", png.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_counts_successes_and_reach_times_over_every_leg() {
        // Two parts; three of four legs reached, in 30, 40 and 50 ticks of 0.1 s.
        let legs: Legs = vec![
            vec![vec![Some(30), None]],
            vec![vec![Some(40)], vec![Some(50)]],
        ];
        let r = Row::of("heavy", "general", &legs, 0.1);
        assert_eq!(r.episodes, 4);
        // Success: 100, 0, 100, 100: mean 75, sd 50, t(3) = 3.182: ± 79.6.
        assert!((r.success_pct.0 - 75.0).abs() < 1e-9);
        assert!((r.success_pct.1 - 3.182_446 * 50.0 / 2.0).abs() < 1e-3);
        // Reach: 3, 4, 5 s: mean 4, sd 1, t(2) = 4.303: ± 2.48.
        assert!((r.reach_s.0 - 4.0).abs() < 1e-9);
        assert!((r.reach_s.1 - 4.302_653 / 3f64.sqrt()).abs() < 1e-3);
        assert_eq!(
            r.line(),
            "heavy: general: 75.0 ± 79.6% of 4 episodes, reach s 4.00 ± 2.48"
        );
    }

    #[test]
    fn the_table_has_a_line_per_world_and_two_columns_per_policy() {
        let legs: Legs = vec![vec![vec![Some(30), Some(50)]]];
        let rows = vec![Row::of("nominal", "a", &legs, 0.1)];
        let worlds = ["nominal".to_string(), "moon".to_string()];
        let md = markdown(&rows, &worlds, &["a".to_string()]);
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines[0], "| world | a success % | a reach s |");
        assert_eq!(lines[2], "| nominal | 100.0 ± 0.0 | 4.00 ± 12.71 |");
        assert_eq!(lines[3], "| moon | | |");
    }
}
