//! What a run shows the person who started it: lines above the progress bar, the bar's
//! message, which of the children's log lines reach the terminal, and a summary line every
//! `run.summary-every` env steps in the way ML-Agents and Stable-Baselines3 users know.
//!
//! The children's routine lines stay in their log files; warnings, errors and anything that
//! is not a log line (a panic) are shown. `--verbose` shows every line.

use super::Progress;
use super::numbers::thousands;
use common::config::PolicySlot;
use common::run_dir;
use indicatif::ProgressBar;
use serde::Deserialize;
use std::collections::VecDeque;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Prints a line above the progress bar, or to stderr when the bar is hidden (not a terminal,
/// `--quiet`), where indicatif would drop it.
pub fn say(bar: &ProgressBar, line: String) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}

/// Which of a child's log lines are shown above the progress bar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lines {
    /// Warnings, errors and lines that are no log lines (a panic, a message before logging
    /// started).
    Notices,
    /// Every line (`--verbose`).
    All,
}

impl Lines {
    pub fn shows(self, line: &str) -> bool {
        self == Lines::All || !is_routine(line)
    }
}

/// A `tracing` line at INFO or below: a timestamp, then the level.
fn is_routine(line: &str) -> bool {
    let mut words = line.split_whitespace();
    let stamped = words
        .next()
        .is_some_and(|w| w.len() >= 20 && w.as_bytes()[4] == b'-' && w.contains('T'));
    stamped
        && words
            .next()
            .is_some_and(|level| matches!(level, "INFO" | "DEBUG" | "TRACE"))
}

/// `125.4` s → `2m 05s`; an hour or more → `1h 02m`.
fn elapsed(secs: f64) -> String {
    let s = secs.max(0.0).round() as u64;
    match (s / 3600, s / 60 % 60, s % 60) {
        (0, 0, s) => format!("{s}s"),
        (0, m, s) => format!("{m}m {s:02}s"),
        (h, m, _) => format!("{h}h {m:02}m"),
    }
}

/// Env steps per second over the last few seconds of ticks.
#[derive(Debug, Default)]
pub struct Rate {
    seen: VecDeque<(Instant, u64)>,
}

impl Rate {
    const SPAN: Duration = Duration::from_secs(5);

    /// Takes the step count seen at `now`; the rate over the samples of the last
    /// [`Self::SPAN`], once there are two.
    pub fn update(&mut self, now: Instant, steps: u64) -> Option<f64> {
        if self.seen.back().is_none_or(|&(_, s)| s != steps) {
            self.seen.push_back((now, steps));
        }
        while self.seen.len() > 2 && now.duration_since(self.seen[1].0) > Self::SPAN {
            self.seen.pop_front();
        }
        let (&(t0, s0), &(t1, s1)) = (self.seen.front()?, self.seen.back()?);
        let dt = t1.duration_since(t0).as_secs_f64();
        (dt > 0.0).then(|| (s1 - s0) as f64 / dt)
    }
}

/// The progress bar's message: steps/s, policy version and lag, success, terrain accuracy.
pub fn bar_message(p: &Progress, rate: Option<f64>) -> String {
    let mut m = format!(
        "{} steps/s · policy v{} (lag {}) · success {:.0}%",
        rate.map_or("-".into(), thousands),
        p.tick.policy_version,
        p.learned_version.saturating_sub(p.tick.policy_version),
        100.0 * p.episodes().success_rate()
    );
    if let Some(a) = p.terrain_accuracy() {
        m.push_str(&format!(" · terrain {:.0}%", 100.0 * a));
    }
    m
}

/// The columns of a learner's `metrics.csv` a summary line shows.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct UpdateRow {
    pub global_step: u64,
    pub mean_episode_return: Option<f64>,
    pub success_rate: Option<f64>,
    pub entropy: f64,
    pub approx_kl: f64,
}

impl UpdateRow {
    /// `general  step 102,400  2m 05s  return 41.2  success 87%  entropy 2.31  KL 0.0123`.
    pub fn line(&self, learner: PolicySlot, secs: f64) -> String {
        format!(
            "{:<8} step {:>11}  {:>7}  return {:>7}  success {:>4}  entropy {:.2}  KL {:.4}",
            learner.name(),
            thousands(self.global_step as f64),
            elapsed(secs),
            self.mean_episode_return
                .map_or("-".into(), |r| format!("{r:.1}")),
            self.success_rate
                .map_or("-".into(), |s| format!("{:.0}%", 100.0 * s)),
            self.entropy,
            self.approx_kl
        )
    }
}

/// The rows a learner appends to its `metrics.csv`, read as they come.
struct Tail {
    path: PathBuf,
    /// Bytes read so far; only whole lines are taken.
    read: u64,
    header: Option<csv::StringRecord>,
}

impl Tail {
    /// The rows completed since the last call; none while the file does not exist.
    fn rows(&mut self) -> Vec<UpdateRow> {
        let mut text = String::new();
        let read = std::fs::File::open(&self.path).and_then(|mut f| {
            f.seek(SeekFrom::Start(self.read))?;
            f.read_to_string(&mut text)
        });
        if read.is_err() {
            return Vec::new();
        }
        let whole = text.rfind('\n').map_or(0, |i| i + 1);
        self.read += whole as u64;
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(&text.as_bytes()[..whole]);
        let mut rows = Vec::new();
        for record in reader.records().map_while(Result::ok) {
            match &self.header {
                None => self.header = Some(record),
                Some(h) => rows.extend(record.deserialize(Some(h)).ok()),
            }
        }
        rows
    }
}

/// Summary lines from the learners' metrics, one per learner every `every` env steps.
pub struct Summaries {
    every: u64,
    learners: Vec<(PolicySlot, Tail, u64)>,
    started: Instant,
}

impl Summaries {
    /// The learners of the run in `run_dir`; `every` = 0 prints none.
    pub fn new(run_dir: &Path, learners: &[PolicySlot], every: u64) -> Self {
        let tail = |slot| Tail {
            path: run_dir::learner_dir(run_dir, slot).join(run_dir::METRICS_CSV),
            read: 0,
            header: None,
        };
        Self {
            every,
            learners: learners.iter().map(|&s| (s, tail(s), 0)).collect(),
            started: Instant::now(),
        }
    }

    /// Prints the lines due: a learner's newest row once it passes the next multiple of
    /// `every` steps.
    pub fn print_due(&mut self, bar: &ProgressBar) {
        if self.every == 0 {
            return;
        }
        let secs = self.started.elapsed().as_secs_f64();
        for (slot, tail, next) in &mut self.learners {
            let Some(row) = tail.rows().pop() else {
                continue;
            };
            if row.global_step >= *next {
                say(bar, row.line(*slot, secs));
                *next = (row.global_step / self.every + 1) * self.every;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routine_log_lines_stay_in_the_log() {
        let info = "2026-12-02T07:26:32.123456Z  INFO update done update=3";
        let warn = "2026-12-02T07:26:32.123456Z  WARN still no policy secs=10";
        let error = "2026-12-02T07:26:32.123456Z ERROR write failed";
        let panic = "thread 'main' panicked at sim-proc/src/serve.rs:10:5:";
        assert!(!Lines::Notices.shows(info));
        assert!(!Lines::Notices.shows(&info.replace("INFO", "DEBUG")));
        for shown in [warn, error, panic, "INFO without a timestamp"] {
            assert!(Lines::Notices.shows(shown), "{shown}");
        }
        assert!(Lines::All.shows(info));
    }

    #[test]
    fn numbers_read_as_people_write_them() {
        assert_eq!(thousands(4_519.971_5), "4,520");
        assert_eq!(thousands(1_234_567.0), "1,234,567");
        assert_eq!(thousands(0.4), "0");
        assert_eq!(thousands(999.0), "999");
        assert_eq!(thousands(-12_000.0), "-12,000");
        assert_eq!(elapsed(7.4), "7s");
        assert_eq!(elapsed(125.4), "2m 05s");
        assert_eq!(elapsed(3_725.0), "1h 02m");
    }

    #[test]
    fn rate_is_over_the_last_seconds() {
        let mut r = Rate::default();
        let t0 = Instant::now();
        assert_eq!(r.update(t0, 0), None);
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        assert_eq!(r.update(at(1.0), 1_000), Some(1_000.0));
        assert_eq!(r.update(at(2.0), 3_000), Some(1_500.0));
        // Ten seconds later only the recent samples count: 4,000 steps/s.
        r.update(at(10.0), 35_000);
        let rate = r.update(at(12.0), 43_000).expect("rate");
        assert!((rate - 4_000.0).abs() < 1e-6, "{rate}");
    }

    #[test]
    fn summary_lines_follow_the_metrics_file_every_so_many_steps() {
        let dir = tempfile::tempdir().expect("tempdir");
        let csv = dir.path().join(run_dir::METRICS_CSV);
        let row = |step: u64| format!("{step},0.5,{},-0.01,2.3051,0.01234,,0.9\n", step / 10);
        let header = "global_step,success_rate,mean_episode_return,policy_loss,entropy,approx_kl,chunks_by_source,x\n";
        std::fs::write(&csv, format!("{header}{}", row(2048))).expect("write");
        let mut s = Summaries::new(dir.path(), &[PolicySlot::General], 4096);
        let rows = s.learners[0].1.rows();
        assert_eq!(
            rows,
            [UpdateRow {
                global_step: 2048,
                mean_episode_return: Some(204.0),
                success_rate: Some(0.5),
                entropy: 2.3051,
                approx_kl: 0.01234,
            }]
        );
        assert_eq!(
            rows[0].line(PolicySlot::General, 125.0),
            "general  step       2,048   2m 05s  return   204.0  success  50%  entropy 2.31  KL 0.0123"
        );
        // A row being written is not read until its line ends.
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&csv)
            .expect("open");
        std::io::Write::write_all(&mut f, b"4096,0.5,").expect("append");
        assert!(s.learners[0].1.rows().is_empty());
        std::io::Write::write_all(&mut f, b"409,-0.01,2.3,0.01,,1\n").expect("append");
        assert_eq!(s.learners[0].1.rows()[0].global_step, 4096);
    }
}
