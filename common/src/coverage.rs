//! How much of a switching run acted on live terrain estimates (docs/EXPERIMENT.md E20),
//! counted from its telemetry CSV's `estimate` and `slot` columns:
//!
//! - **with an estimate**: of each env's decision ticks from its first estimate on, the share
//!   on which the sim held one;
//! - **estimates right**: of those with an estimate, the share naming the ground under the
//!   robot (a window straddling a boundary still reads the ground it left);
//! - **acting on it**: of the ticks whose estimate had held for the dwell the switch needs to
//!   leave the slot it was in (SPEC S8), the share acted by that estimate's specialist;
//! - **switches per 100 m**: changes of the acting slot per 100 m driven (placements' jumps
//!   are not driven);
//! - **detection delay**, per kind: at every crossing into ground of a kind (the true ground
//!   changed between two ticks of an env, by driving or by a placement), the ticks until its
//!   specialist acts; a crossing left before that is missed.

use crate::TelemetryRow;
use crate::config::{AreaKind, PolicySlot};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A switching run's coverage: see the module's definitions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    /// Decision ticks counted: each env's from its first estimate on.
    pub ticks: u64,
    /// Of `ticks`, the share with an estimate.
    pub with_estimate: f64,
    /// Of the ticks with an estimate, the share naming the ground under the robot; `None` in
    /// a record of an older lavatube, which did not count it.
    #[serde(default)]
    pub estimate_right: Option<f64>,
    /// Ticks whose estimate had held for the dwell.
    pub settled: u64,
    /// Of `settled`, the share acted by the estimate's specialist.
    pub acting_on_estimate: f64,
    pub switches: u64,
    /// Metres driven (between consecutive ticks of an episode).
    pub metres: f64,
    pub switches_per_100m: f64,
    /// Per kind crossed into: crossings, how many its specialist acted on, and the delay.
    pub crossings: BTreeMap<AreaKind, Crossings>,
}

/// The crossings into one kind's ground.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Crossings {
    pub crossings: u64,
    /// Crossings on which the kind's specialist acted before the robot left the ground.
    pub detected: u64,
    /// Mean ticks from the crossing's tick (0) to the first its specialist acted on, over
    /// the detected ones; 0 without one.
    pub mean_delay_ticks: f64,
}

impl Coverage {
    /// The live accuracy as a percentage with one decimal, `-` when not counted.
    pub fn right_pct(&self) -> String {
        self.estimate_right
            .map_or("-".into(), |r| format!("{:.1}", 100.0 * r))
    }

    /// Each kind crossed into, `kind detected/crossings after D s` at decision step `dt`
    /// seconds, comma-separated; `None` when the robots crossed no ground.
    pub fn crossings_text(&self, dt: f64) -> Option<String> {
        let parts: Vec<String> = self
            .crossings
            .iter()
            .map(|(k, x)| {
                format!(
                    "{} {}/{} after {:.2} s",
                    k.name(),
                    x.detected,
                    x.crossings,
                    x.mean_delay_ticks * dt
                )
            })
            .collect();
        (!parts.is_empty()).then(|| parts.join(", "))
    }

    /// The coverage of the telemetry CSVs at `paths`, each its own recording, of a run that
    /// switched as `sim` says ([`crate::config::SimConfig::dwell_leaving`]).
    pub fn of_files(
        paths: &[std::path::PathBuf],
        sim: &crate::config::SimConfig,
    ) -> Result<Self, crate::telemetry::TelemetryError> {
        let mut counter = Counter::new(|s| sim.dwell_leaving(s));
        for path in paths {
            for row in crate::telemetry::TelemetryReader::open(path)? {
                counter.see(&row?.1);
            }
            counter.end_recording();
        }
        Ok(counter.finish())
    }
}

/// One env's count as the rows go by.
#[derive(Debug, Clone, Default)]
struct EnvCount {
    last: Option<TelemetryRow>,
    started: bool,
    /// The current estimate and the ticks it has held, this one included.
    held: Option<(AreaKind, u32)>,
    /// The kind crossed into and the ticks since, while its specialist has not acted.
    waiting: Option<(AreaKind, u64)>,
}

/// What the rows so far add up to.
#[derive(Debug, Default)]
struct Tally {
    ticks: u64,
    estimated: u64,
    right: u64,
    settled: u64,
    agreed: u64,
    switches: u64,
    metres: f64,
    /// Per kind: its crossings and the sum of the detected ones' delays, ticks.
    crossings: BTreeMap<AreaKind, (Crossings, u64)>,
}

impl Tally {
    /// Takes env `env`'s next row, leaving a slot after `dwell(slot)` ticks.
    fn see(&mut self, env: &mut EnvCount, row: &TelemetryRow, dwell: &dyn Fn(PolicySlot) -> u32) {
        if let Some(last) = &env.last {
            if last.episode == row.episode {
                self.metres += (row.x - last.x).hypot(row.z - last.z);
            }
            if last.slot.is_some() && row.slot.is_some() && last.slot != row.slot {
                self.switches += 1;
            }
            if last.area != row.area {
                self.miss(env.waiting.take());
                env.waiting = Some((row.area, 0));
            }
        }
        self.count_estimate(env, row, dwell);
        self.count_detection(env, row);
        env.last = Some(*row);
    }

    fn count_estimate(
        &mut self,
        env: &mut EnvCount,
        row: &TelemetryRow,
        dwell: &dyn Fn(PolicySlot) -> u32,
    ) {
        env.held = row.estimate.map(|k| match env.held {
            Some((held, n)) if held == k => (k, n + 1),
            _ => (k, 1),
        });
        env.started |= row.estimate.is_some();
        if !env.started {
            return;
        }
        self.ticks += 1;
        let Some((kind, held)) = env.held else {
            return;
        };
        self.estimated += 1;
        self.right += u64::from(kind == row.area);
        let specialist = PolicySlot::for_class(kind.code());
        let leaving = env.last.as_ref().and_then(|l| l.slot).or(row.slot);
        if let (Some(specialist), Some(from)) = (specialist, leaving)
            && (from == specialist || held >= dwell(from))
        {
            self.settled += 1;
            self.agreed += u64::from(row.slot == Some(specialist));
        }
    }

    fn count_detection(&mut self, env: &mut EnvCount, row: &TelemetryRow) {
        let Some((kind, since)) = env.waiting else {
            return;
        };
        if row.slot.and_then(PolicySlot::kind) == Some(kind) {
            let (c, delays) = self.crossings.entry(kind).or_default();
            c.crossings += 1;
            c.detected += 1;
            *delays += since;
            env.waiting = None;
        } else {
            env.waiting = Some((kind, since + 1));
        }
    }

    /// A crossing the robot left (or the recording ended) before its specialist acted.
    fn miss(&mut self, waiting: Option<(AreaKind, u64)>) {
        if let Some((kind, _)) = waiting {
            self.crossings.entry(kind).or_default().0.crossings += 1;
        }
    }
}

/// Counts coverage over telemetry rows (any env order), leaving a slot after `dwell(slot)`
/// ticks of a new estimate as the switch does.
pub struct Counter<F: Fn(PolicySlot) -> u32> {
    dwell: F,
    envs: BTreeMap<u32, EnvCount>,
    tally: Tally,
}

impl<F: Fn(PolicySlot) -> u32> Counter<F> {
    pub fn new(dwell: F) -> Self {
        Self {
            dwell,
            envs: BTreeMap::new(),
            tally: Tally::default(),
        }
    }

    /// Takes one row.
    pub fn see(&mut self, row: &TelemetryRow) {
        let env = self.envs.entry(row.env).or_default();
        self.tally.see(env, row, &self.dwell);
    }

    /// Ends a recording: its crossings still waiting count as missed, and the next rows
    /// (another recording's, whose env ids start again) start every env afresh.
    pub fn end_recording(&mut self) {
        for env in std::mem::take(&mut self.envs).into_values() {
            self.tally.miss(env.waiting);
        }
    }

    /// The coverage of every row seen; crossings still waiting at the end count as missed.
    pub fn finish(mut self) -> Coverage {
        self.end_recording();
        let t = self.tally;
        let share = |n: u64, of: u64| if of == 0 { 0.0 } else { n as f64 / of as f64 };
        Coverage {
            ticks: t.ticks,
            with_estimate: share(t.estimated, t.ticks),
            estimate_right: Some(share(t.right, t.estimated)),
            settled: t.settled,
            acting_on_estimate: share(t.agreed, t.settled),
            switches: t.switches,
            metres: t.metres,
            switches_per_100m: if t.metres > 0.0 {
                100.0 * t.switches as f64 / t.metres
            } else {
                0.0
            },
            crossings: t
                .crossings
                .into_iter()
                .map(|(k, (c, delays))| {
                    let mean_delay_ticks = share(delays, c.detected);
                    (
                        k,
                        Crossings {
                            mean_delay_ticks,
                            ..c
                        },
                    )
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests;
