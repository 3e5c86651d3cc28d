//! What an evaluation drove, leg by leg, read from its telemetry, and the success and reach
//! time of a cell of legs.

use common::config::AreaKind;
use common::telemetry::TelemetryReader;
use std::path::Path;

/// Each leg an evaluation drove, by run (part), env and leg: its length in decision steps
/// when the robot reached the target, `None` when the leg failed. Stage f drives every model
/// on the same seeded courses (`EpisodeStart::Course`), so two models' legs pair up by index.
pub(crate) type Legs = Vec<Vec<Vec<Option<u32>>>>;

/// One evaluation cell: a model in an area.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct Cell {
    pub(crate) episodes: u64,
    pub(crate) successes: u64,
    /// Reach time of successful episodes, seconds.
    pub(crate) mean_reach_s: f64,
    pub(crate) std_reach_s: f64,
}

impl Cell {
    /// Success count and reach-time moments of every leg in `legs`.
    pub(crate) fn of(legs: &Legs, decision_dt: f64) -> Self {
        let (episodes, reach) = reach_times(legs, decision_dt);
        let n = reach.len().max(1) as f64;
        let mean = reach.iter().sum::<f64>() / n;
        let var = reach.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n;
        Self {
            episodes: episodes as u64,
            successes: reach.len() as u64,
            mean_reach_s: mean,
            std_reach_s: var.sqrt(),
        }
    }

    pub(crate) fn success_pct(&self) -> f64 {
        100.0 * self.successes as f64 / self.episodes.max(1) as f64
    }

    /// `mean (std)` of the reach time, or `-` when no episode succeeded.
    pub(crate) fn reach(&self) -> String {
        if self.successes == 0 {
            "-".into()
        } else {
            format!("{:.2} ({:.2})", self.mean_reach_s, self.std_reach_s)
        }
    }
}

/// How many legs `legs` holds, and the reach time of each that reached its target, seconds
/// at `decision_dt` per step.
pub(crate) fn reach_times(legs: &Legs, decision_dt: f64) -> (usize, Vec<f64>) {
    let all = legs.iter().flatten().flatten();
    let reach = all
        .clone()
        .flatten()
        .map(|&t| f64::from(t) * decision_dt)
        .collect();
    (all.count(), reach)
}

/// A model's evaluation in an area: every leg it drove.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Evaluated {
    pub(super) model: String,
    pub(super) area: AreaKind,
    pub(super) legs: Legs,
    /// How much of a switching model's driving acted on live estimates; `None` for a model
    /// that drove alone.
    #[serde(default)]
    pub(super) coverage: Option<common::coverage::Coverage>,
}

/// The legs each env ended in a telemetry CSV (`sim-proc --telemetry`), in order: a leg's
/// length runs from the env's first row after the previous ending to the row that ends it.
/// Legs still running at the end are left out.
pub(crate) fn legs_in(path: &Path) -> anyhow::Result<Vec<Vec<Option<u32>>>> {
    let mut legs: Vec<Vec<Option<u32>>> = Vec::new();
    let mut length: Vec<u32> = Vec::new();
    for row in TelemetryReader::open(path)? {
        let (_, row) = row?;
        let (e, leg) = (row.env as usize, row.episode as usize);
        if e >= legs.len() {
            legs.resize(e + 1, Vec::new());
            length.resize(e + 1, 0);
        }
        // A sim restarted inside a run starts its courses again: its legs would not pair.
        anyhow::ensure!(
            leg == legs[e].len(),
            "{}: env {e} is on leg {leg} after ending {} (the sim restarted?)",
            path.display(),
            legs[e].len()
        );
        length[e] += 1;
        if row.terminated || row.truncated {
            legs[e].push(row.success.then_some(length[e]));
            length[e] = 0;
        }
    }
    Ok(legs)
}

/// The legs every one of `legs` drove (same part, env and leg index): per leg, each one's
/// outcome, in the order of `legs`.
pub(super) fn common_legs(legs: &[&Legs]) -> Vec<Vec<Option<u32>>> {
    let shortest = |len: &dyn Fn(&Legs) -> usize| legs.iter().map(|l| len(l)).min().unwrap_or(0);
    let mut out = Vec::new();
    for part in 0..shortest(&|l| l.len()) {
        for env in 0..shortest(&|l| l[part].len()) {
            for leg in 0..shortest(&|l| l[part][env].len()) {
                out.push(legs.iter().map(|l| l[part][env][leg]).collect());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes telemetry rows `(env, episode, ending)` as `sim-proc --telemetry` does; the
    /// ending is `Some(success)` on a leg's last row.
    fn write_telemetry(path: &Path, rows: &[(u32, u64, Option<bool>)]) {
        let mut w = csv::Writer::from_path(path).expect("csv");
        for (tick, &(env, episode, ending)) in rows.iter().enumerate() {
            w.serialize(common::TelemetryRow {
                env,
                tick: tick as u64,
                episode,
                terminated: ending == Some(true),
                truncated: ending == Some(false),
                success: ending == Some(true),
                ..Default::default()
            })
            .expect("row");
        }
        w.flush().expect("flush");
    }

    #[test]
    fn legs_and_reach_times_come_from_the_telemetry() {
        let dir = tempfile::tempdir().expect("tempdir");
        let csv = dir.path().join("t.csv");
        // env 0: success after 2 ticks, then a truncation after 2, then one leg unfinished;
        // env 1: success after 1.
        write_telemetry(
            &csv,
            &[
                (0, 0, None),
                (1, 0, Some(true)),
                (0, 0, Some(true)),
                (0, 1, None),
                (0, 1, Some(false)),
                (0, 2, None),
            ],
        );
        let legs = legs_in(&csv).expect("parse");
        assert_eq!(legs, vec![vec![Some(2), None], vec![Some(1)]]);
        // Reach times {0.2, 0.1} s of 3 legs.
        let c = Cell::of(&vec![legs], 0.1);
        assert_eq!((c.episodes, c.successes), (3, 2));
        assert!((c.mean_reach_s - 0.15).abs() < 1e-12 && (c.std_reach_s - 0.05).abs() < 1e-12);
        // A sim that restarted starts its legs again: those rows cannot pair.
        write_telemetry(&csv, &[(0, 0, Some(true)), (0, 0, None)]);
        let e = legs_in(&csv).expect_err("restart");
        assert!(
            e.to_string().contains("env 0 is on leg 0 after ending 1"),
            "{e}"
        );
        // A file of another layout is refused, naming the file and what it lacks.
        std::fs::write(&csv, "env,episode\n0,x\n").expect("write");
        let e = format!("{:#}", legs_in(&csv).expect_err("layout"));
        assert!(e.contains("t.csv: missing column"), "{e}");
    }
}
