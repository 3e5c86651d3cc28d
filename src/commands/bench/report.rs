//! The results: the stage table (throughput), the process table (CPU time and peak memory),
//! the transport table (iceoryx2 versus the socket), the acceptance checks, and
//! the same as JSON with the units in the key names and spelled out in `units`.

use super::bridge::{Bridged, SimRates};
use super::config::{Plan, Stage};
use super::stages::Row;
use super::transport::TransportRow;
use crate::runtime::thousands;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Target: publishing through iceoryx2 costs less than 5 % of the decision rate.
pub const PUBLISH_OVER_POLICY_TARGET: f64 = 0.95;
/// Target: env steps per second while learning (stages d and e), on a 2-core machine.
pub const LEARNING_TARGET: f64 = 4200.0;

/// Where the numbers were taken: they mean little without the machine and its load.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    pub cpus: usize,
    pub cpu_model: Option<String>,
    /// `/proc/loadavg`'s one-minute load when the bench started and ended.
    pub load_1m_start: Option<f64>,
    pub load_1m_end: Option<f64>,
}

impl Machine {
    pub fn now() -> Self {
        let cpu_model = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        });
        Self {
            cpus: std::thread::available_parallelism().map_or(1, std::num::NonZero::get),
            cpu_model,
            load_1m_start: load_1m(),
            load_1m_end: None,
        }
    }
}

pub fn load_1m() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// What was measured with what.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    pub runtime_config: Option<PathBuf>,
    pub envs: Vec<usize>,
    pub threads: Vec<usize>,
    pub env_steps_per_measurement: u64,
    pub min_chunks: u64,
    pub repeats: usize,
    pub seed: u64,
    pub ground: &'static str,
    pub substeps: usize,
    pub physics_dt_s: f64,
    pub rollout_transitions: usize,
    pub ppo_epochs: usize,
    pub minibatch_size: usize,
    pub policy_hidden: Vec<usize>,
    pub policy_params: usize,
    pub transport_messages: usize,
}

impl Settings {
    pub fn of(plan: &Plan, policy_params: usize) -> Self {
        let (b, r) = (&plan.bench, &plan.runtime);
        Self {
            runtime_config: b.runtime.clone(),
            envs: b.envs.clone(),
            threads: b.threads.clone(),
            env_steps_per_measurement: b.env_steps,
            min_chunks: b.min_chunks,
            repeats: b.repeats,
            seed: r.run.seed,
            ground: "rough",
            substeps: r.sim.substeps,
            physics_dt_s: r.sim.physics_dt,
            rollout_transitions: r.ppo.rollout_transitions,
            ppo_epochs: r.ppo.epochs,
            minibatch_size: r.ppo.minibatch_size,
            policy_hidden: r.ppo.hidden.clone(),
            policy_params,
            transport_messages: b.transport_messages,
        }
    }
}

/// A stage in one cell over its repeats: the run with the median rate, and every run's rate.
#[derive(Debug, Clone, Serialize)]
pub struct StageCell {
    #[serde(flatten)]
    pub median: Row,
    /// Every repeat's decision steps/s, in the order measured.
    pub decision_steps_per_s_repeats: Vec<f64>,
}

impl StageCell {
    /// (max − min) / median of the repeats' rates, percent: how much the machine wandered.
    fn spread_pct(&self) -> f64 {
        let r = &self.decision_steps_per_s_repeats;
        let (lo, hi) = r.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
        100.0 * (hi - lo) / self.median.decision_steps_per_s
    }
}

/// The lower median: the middle value for an odd count, the lower of the two middle ones
/// for an even count (a pass on it is never a pass on luck alone).
fn lower_median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[(xs.len() - 1) / 2]
}

fn same_cell(a: &Row, b: &Row) -> bool {
    (a.stage, a.envs, a.threads) == (b.stage, b.envs, b.threads)
}

/// Groups the runs by stage and cell, in the order first measured, keeping each group's
/// median run.
fn stage_cells(runs: &[Row]) -> Vec<StageCell> {
    let mut out: Vec<StageCell> = Vec::new();
    for r in runs {
        if out.iter().any(|c| same_cell(&c.median, r)) {
            continue;
        }
        let mut group: Vec<&Row> = runs.iter().filter(|x| same_cell(x, r)).collect();
        let rates = group.iter().map(|x| x.decision_steps_per_s).collect();
        group.sort_by(|x, y| x.decision_steps_per_s.total_cmp(&y.decision_steps_per_s));
        out.push(StageCell {
            median: group[(group.len() - 1) / 2].clone(),
            decision_steps_per_s_repeats: rates,
        });
    }
    out
}

/// Stage c against stage b in one cell.
#[derive(Debug, Clone, Serialize)]
pub struct RatioCheck {
    pub envs: usize,
    pub threads: usize,
    /// The median runs' rates.
    pub stage_b_decision_steps_per_s: f64,
    pub stage_c_decision_steps_per_s: f64,
    /// Per repeat, stage c over the stage b run right before it.
    pub ratios: Vec<f64>,
    /// Their lower median: what `pass` is decided on.
    pub ratio: f64,
    pub pass: bool,
}

/// A learning stage against the target in one cell.
#[derive(Debug, Clone, Serialize)]
pub struct RateCheck {
    pub stage: char,
    pub envs: usize,
    pub threads: usize,
    pub decision_steps_per_s: f64,
    pub pass: bool,
    /// For a miss: what the same cell reached without the learner (stage c), which tells
    /// whether the sim or the learner holds it back.
    pub without_learner_decision_steps_per_s: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Acceptance {
    pub publish_over_policy_target: f64,
    pub publish_over_policy: Vec<RatioCheck>,
    pub learning_decision_steps_per_s_target: f64,
    pub learning: Vec<RateCheck>,
}

impl Acceptance {
    /// The checks on the median runs of `stages`, and for stage c on its pairs in `runs`.
    fn of(stages: &[StageCell], runs: &[Row]) -> Self {
        let find = |stage: Stage, envs, threads| {
            stages
                .iter()
                .map(|c| &c.median)
                .find(|r| r.stage == stage.letter() && r.envs == envs && r.threads == threads)
        };
        let mut publish_over_policy = Vec::new();
        let mut learning = Vec::new();
        for r in stages.iter().map(|c| &c.median) {
            if r.stage == Stage::Publish.letter()
                && let Some(b) = find(Stage::Policy, r.envs, r.threads)
            {
                let ratios: Vec<f64> = runs
                    .iter()
                    .filter(|c| same_cell(c, r))
                    .filter_map(|c| {
                        runs.iter()
                            .find(|x| same_cell(x, b) && x.repeat == c.repeat)
                            .map(|b| c.decision_steps_per_s / b.decision_steps_per_s)
                    })
                    .collect();
                let ratio = lower_median(ratios.clone());
                publish_over_policy.push(RatioCheck {
                    envs: r.envs,
                    threads: r.threads,
                    stage_b_decision_steps_per_s: b.decision_steps_per_s,
                    stage_c_decision_steps_per_s: r.decision_steps_per_s,
                    ratios,
                    ratio,
                    pass: ratio >= PUBLISH_OVER_POLICY_TARGET,
                });
            }
            if r.stage == Stage::Sync.letter() || r.stage == Stage::Async.letter() {
                let pass = r.decision_steps_per_s >= LEARNING_TARGET;
                learning.push(RateCheck {
                    stage: r.stage,
                    envs: r.envs,
                    threads: r.threads,
                    decision_steps_per_s: r.decision_steps_per_s,
                    pass,
                    without_learner_decision_steps_per_s: (!pass)
                        .then(|| find(Stage::Publish, r.envs, r.threads))
                        .flatten()
                        .map(|c| c.decision_steps_per_s),
                });
            }
        }
        Self {
            publish_over_policy_target: PUBLISH_OVER_POLICY_TARGET,
            publish_over_policy,
            learning_decision_steps_per_s_target: LEARNING_TARGET,
            learning,
        }
    }
}

/// Everything `bench.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub schema: &'static str,
    pub bench_id: String,
    /// `--quick`: the numbers check the tool; do not quote them.
    pub quick: bool,
    pub unix_time_s: u64,
    pub machine: Machine,
    pub settings: Settings,
    pub units: BTreeMap<&'static str, &'static str>,
    /// One entry per stage × envs × threads, in the order measured: its median run over
    /// `settings.repeats`, with every repeat's rate.
    pub stages: Vec<StageCell>,
    /// One entry per payload.
    pub transport: Vec<TransportRow>,
    /// Rollout chunks and policies through a pair of `bridge-proc`s on loopback (DESIGN §9),
    /// and one sim's env steps/s behind the bridge against on one host.
    pub bridge: Bridged,
    pub bridge_sim: SimRates,
    pub acceptance: Acceptance,
}

fn units() -> BTreeMap<&'static str, &'static str> {
    BTreeMap::from([
        (
            "decision_steps",
            "one policy action applied to one env; summed over envs",
        ),
        (
            "physics_steps",
            "rapier steps: decision steps × sim.substeps, summed over envs",
        ),
        ("env_steps", "decision steps summed over envs"),
        ("ticks", "decision steps of every env at once"),
        ("*_per_s", "per second of wall time"),
        (
            "learner_samples_per_s",
            "PPO minibatch samples × epochs per second of update time",
        ),
        (
            "policy_lag_versions",
            "policy versions the acting policy was behind the learner's",
        ),
        ("*_us", "microseconds"),
        ("*_s", "seconds"),
        ("peak_rss_mib", "peak resident set size, MiB (2^20 bytes)"),
        ("bytes", "bytes of payload per message"),
        (
            "ratios",
            "dimensionless; above 1 means iceoryx2 did better than the socket",
        ),
        ("load_1m", "one-minute load average (runnable processes)"),
    ])
}

impl Report {
    pub fn new(
        plan: &Plan,
        bench_id: String,
        machine: Machine,
        policy_params: usize,
        runs: Vec<Row>,
        transport: Vec<TransportRow>,
        (bridge, bridge_sim): (Bridged, SimRates),
    ) -> Self {
        let stages = stage_cells(&runs);
        Self {
            schema: "lavatube.bench.v1",
            bench_id,
            quick: plan.quick,
            unix_time_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            machine,
            settings: Settings::of(plan, policy_params),
            units: units(),
            acceptance: Acceptance::of(&stages, &runs),
            stages,
            transport,
            bridge,
            bridge_sim,
        }
    }

    /// The stage table and the per-process CPU and memory table.
    fn stage_tables(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "\n{:<18} {:>4} {:>3} {:>11} {:>7} {:>11} {:>12} {:>5} {:>9} {:>9} {:>7}",
            "stage",
            "N",
            "thr",
            "decision/s",
            "spread",
            "physics/s",
            "learn smp/s",
            "lag",
            "p50 µs",
            "p99 µs",
            "missed"
        );
        for c in &self.stages {
            let r = &c.median;
            let missed = match (r.telemetry_ticks_missed, r.rollout_chunks_missed) {
                (Some(a), Some(b)) => format!("{a}/{b}"),
                _ => "-".into(),
            };
            let _ = writeln!(
                t,
                "{:<18} {:>4} {:>3} {:>11} {:>7} {:>11} {:>12} {:>5} {:>9} {:>9} {:>7}",
                format!("{} {}", r.stage, r.stage_name),
                r.envs,
                r.threads,
                thousands(r.decision_steps_per_s),
                format!("{:.0}%", c.spread_pct()),
                thousands(r.physics_steps_per_s),
                r.learner_samples_per_s.map_or("-".into(), thousands),
                r.policy_lag_versions
                    .map_or("-".into(), |l| format!("{l:.2}")),
                r.transport_latency_p50_us
                    .map_or("-".into(), |l| format!("{l:.1}")),
                r.transport_latency_p99_us
                    .map_or("-".into(), |l| format!("{l:.1}")),
                missed,
            );
        }
        let _ = writeln!(
            t,
            "(the median of {} run(s) per row; spread: (max − min) / median of their decision/s; missed: telemetry ticks / rollout chunks the reader did not get)",
            self.settings.repeats
        );
        let procs = ["sim", "reader", "learner", "estimator"];
        let _ = write!(t, "\n{:<18} {:>4} {:>3}", "CPU s / peak MiB", "N", "thr");
        for p in procs {
            let _ = write!(t, " {p:>16}");
        }
        let _ = writeln!(t);
        for r in self.stages.iter().map(|c| &c.median) {
            let _ = write!(
                t,
                "{:<18} {:>4} {:>3}",
                format!("{} {}", r.stage, r.stage_name),
                r.envs,
                r.threads
            );
            for p in procs {
                let cell = r.processes.get(p).map_or("-".into(), |u| {
                    format!("{:.2} / {:.0}", u.cpu_s(), u.peak_rss_mib)
                });
                let _ = write!(t, " {cell:>16}");
            }
            let _ = writeln!(t);
        }
    }

    /// The tables and the acceptance checks, as printed.
    pub fn text(&self) -> String {
        let mut t = String::new();
        self.heading(&mut t);
        if !self.stages.is_empty() {
            self.stage_tables(&mut t);
        }
        if !self.bridge.rows.is_empty() {
            self.bridge_table(&mut t);
        }
        if !self.transport.is_empty() {
            self.transport_table(&mut t);
        }
        let _ = writeln!(t);
        self.acceptance_lines(&mut t);
        t
    }

    /// The first line: the bench, the machine and its load, the ground and the policy.
    fn heading(&self, t: &mut String) {
        let m = &self.machine;
        let load = |l: Option<f64>| l.map_or("?".into(), |l| format!("{l:.2}"));
        let _ = writeln!(
            t,
            "lavatube bench {}{}: {} CPUs ({}), load {} → {}; rough ground, {} physics steps per decision, policy {:?} ({} params)",
            self.bench_id,
            if self.quick {
                " (--quick: not for quoting)"
            } else {
                ""
            },
            m.cpus,
            m.cpu_model.as_deref().unwrap_or("unknown CPU"),
            load(m.load_1m_start),
            load(m.load_1m_end),
            self.settings.substeps,
            self.settings.policy_hidden,
            self.settings.policy_params,
        );
    }

    /// The bridge table, the time a joining sim host waits for its policy, and one sim's rate
    /// behind the bridge against on one host.
    fn bridge_table(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "\n{:<26} {:>8} {:>22} {:>10} {:>8}",
            "through the Zenoh bridge", "bytes", "latency p50 / p99", "msg/s", "MB/s"
        );
        for b in &self.bridge.rows {
            let us = |x: Option<f64>| x.map_or("?".into(), |x| format!("{x:.0}"));
            let _ = writeln!(
                t,
                "{:<26} {:>8} {:>22} {:>10} {:>8.1}",
                b.what,
                b.bytes,
                format!("{} / {} µs", us(b.latency_p50_us), us(b.latency_p99_us)),
                thousands(b.messages_per_s),
                b.mb_per_s
            );
        }
        let _ = writeln!(
            t,
            "a sim host joining a run under way has its policy {:.0} ms after its bridge starts",
            self.bridge.join_to_policy_ms
        );
        let s = &self.bridge_sim;
        let _ = writeln!(
            t,
            "one sim, async, {} env steps: {} steps/s behind the bridge, {} on one host ({:.2}×)",
            s.env_steps,
            thousands(s.bridged_steps_per_s),
            thousands(s.local_steps_per_s),
            s.bridged_over_local
        );
    }

    /// The same bytes over iceoryx2 and over the socket, payload by payload, and the ratios.
    fn transport_table(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "\n{:<18} {:>8} {:>17} {:>10} {:>17} {:>10} {:>6} {:>6} {:>6}",
            "same bytes over",
            "bytes",
            "iceoryx2 p50/p99",
            "msg/s",
            "socket p50/p99",
            "msg/s",
            "p50 ×",
            "p99 ×",
            "msg ×"
        );
        for x in &self.transport {
            let label = match x.envs {
                Some(n) => format!("{} N={n}", x.payload.name()),
                None => x.payload.name().to_string(),
            };
            let _ = writeln!(
                t,
                "{:<18} {:>8} {:>17} {:>10} {:>17} {:>10} {:>6.2} {:>6.2} {:>6.2}",
                label,
                x.bytes,
                format!(
                    "{:.1} / {:.1} µs",
                    x.iceoryx2.latency_p50_us, x.iceoryx2.latency_p99_us
                ),
                thousands(x.iceoryx2.messages_per_s),
                format!(
                    "{:.1} / {:.1} µs",
                    x.uds.latency_p50_us, x.uds.latency_p99_us
                ),
                thousands(x.uds.messages_per_s),
                x.ratios.latency_p50_uds_over_iceoryx2,
                x.ratios.latency_p99_uds_over_iceoryx2,
                x.ratios.messages_per_s_iceoryx2_over_uds,
            );
        }
        let _ = writeln!(
            t,
            "(×: socket latency / iceoryx2 latency, iceoryx2 msg/s / socket msg/s; above 1 favours shared memory)"
        );
    }

    /// One line per acceptance check: stage c against stage b, then each learning stage
    /// against its target.
    fn acceptance_lines(&self, t: &mut String) {
        let a = &self.acceptance;
        if let Some(worst) = a
            .publish_over_policy
            .iter()
            .min_by(|x, y| x.ratio.total_cmp(&y.ratio))
        {
            let passed = a.publish_over_policy.iter().filter(|c| c.pass).count();
            let _ = writeln!(
                t,
                "stage c ≥ {:.2} × stage b (median over repeats of c / the b run before it): {passed} of {} cells pass; lowest {:.3} at N={}, {} thread(s)",
                a.publish_over_policy_target,
                a.publish_over_policy.len(),
                worst.ratio,
                worst.envs,
                worst.threads,
            );
        }
        for stage in [Stage::Sync, Stage::Async] {
            let cells: Vec<&RateCheck> = a
                .learning
                .iter()
                .filter(|c| c.stage == stage.letter())
                .collect();
            if let Some(best) = cells
                .iter()
                .max_by(|x, y| x.decision_steps_per_s.total_cmp(&y.decision_steps_per_s))
            {
                let passed = cells.iter().filter(|c| c.pass).count();
                let _ = writeln!(
                    t,
                    "stage {} ≥ {} env steps/s: {passed} of {} cells pass; best {} at N={}, {} thread(s)",
                    stage.letter(),
                    thousands(a.learning_decision_steps_per_s_target),
                    cells.len(),
                    thousands(best.decision_steps_per_s),
                    best.envs,
                    best.threads,
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(stage: Stage, repeat: usize, rate: f64) -> Row {
        Row {
            wall_s: 1.0,
            decision_steps_per_s: rate,
            physics_steps_per_s: 4.0 * rate,
            episodes: 3,
            ..Row::unmeasured(stage, 8, 2, repeat, None, 100)
        }
    }

    #[test]
    fn each_stage_keeps_its_median_run_and_c_is_paired_with_the_b_before_it() {
        // Round 1 ran on a slow machine: b and c both lost 30 %.
        let runs = vec![
            run(Stage::Policy, 0, 5000.0),
            run(Stage::Publish, 0, 4900.0),
            run(Stage::Policy, 1, 3500.0),
            run(Stage::Publish, 1, 3400.0),
            run(Stage::Policy, 2, 4600.0),
            run(Stage::Publish, 2, 4200.0),
        ];
        let cells = stage_cells(&runs);
        assert_eq!(cells.len(), 2);
        assert_eq!(cells[0].median.repeat, 2, "b's median run is 4600");
        assert_eq!(
            cells[1].decision_steps_per_s_repeats,
            [4900.0, 3400.0, 4200.0]
        );
        assert!((cells[1].spread_pct() - 100.0 * 1500.0 / 4200.0).abs() < 1e-9);
        let a = Acceptance::of(&cells, &runs);
        let c = &a.publish_over_policy[0];
        // Pairs: 0.98, 0.971, 0.913; medians of the unpaired rates would give 4200/4600 = 0.913.
        assert_eq!(c.ratios.len(), 3);
        assert!((c.ratio - 3400.0 / 3500.0).abs() < 1e-12, "{}", c.ratio);
        assert!(c.pass);
        assert_eq!(lower_median(vec![4.0, 1.0, 3.0, 2.0]), 2.0);
    }
}
