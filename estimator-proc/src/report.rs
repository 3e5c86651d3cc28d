//! Result files: JSON for programs, Markdown for people (the paper's Table 3 layout with the
//! paper's own numbers beside ours).

use crate::analysis::{AREAS, PAPER_TABLE_3, PaperRow, WindowResult};
use crate::evaluation::{ClassifierScore, OnlineEval};
use crate::{EstimatorError, Result};
use common::config::{AttitudeSource, MixtureFeature};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// How many series of each area went into the analysis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SeriesCount {
    pub flat: usize,
    pub rough: usize,
}

/// Everything `analyze` found (SPEC S7), as written to `results.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AnalysisReport {
    pub input: String,
    pub warmup_ticks: usize,
    pub seed: u64,
    pub components: usize,
    /// Mixing weights held at 1/K (`estimator.equal-weights`), not fitted.
    pub equal_weights: bool,
    /// The rolling-std convention.
    pub std: &'static str,
    /// Whose sin θx: the simulator's pose (`truth`) or the IMU filter's (`imu`).
    pub signal: AttitudeSource,
    pub series: SeriesCount,
    pub windows: Vec<WindowResult>,
    pub paper_table_3: Vec<PaperRow>,
    /// PNG files written beside this report.
    pub figures: Vec<String>,
}

/// The online evaluation, as written to `online.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OnlineReport {
    pub input: String,
    pub splice: bool,
    pub hold: usize,
    pub seed: u64,
    pub windows: Vec<OnlineEval>,
}

/// Writes `contents` to `path`, naming the path on failure.
pub fn write_file(path: &Path, contents: &str) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| EstimatorError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Creates `dir` and its parents if missing, naming it on failure.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| EstimatorError::Write {
        path: dir.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Writes a report's text to stdout: the CLI's output to its user.
#[allow(
    clippy::print_stdout,
    reason = "the CLI prints its results table to the user"
)]
pub fn print_output(text: &str) {
    println!("{text}");
}

/// Pretty JSON of any report.
pub fn to_json<T: Serialize>(report: &T) -> String {
    serde_json::to_string_pretty(report).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// `mean (std)` of every component, ` / `-separated (flat first).
fn components_cell(r: &WindowResult) -> String {
    r.components_in_std()
        .iter()
        .map(|(m, s)| format!("{m:.3} ({s:.3})"))
        .collect::<Vec<_>>()
        .join(" / ")
}

impl AnalysisReport {
    /// Table 3 of the paper, ours beside theirs, then each window's confusion matrix.
    pub fn to_markdown(&self) -> String {
        let mut md = String::new();
        self.write_intro(&mut md);
        self.write_table_3(&mut md);
        self.write_confusions(&mut md);
        self.write_figures(&mut md);
        md
    }

    /// The title and the paragraph saying what was analysed and how.
    fn write_intro(&self, md: &mut String) {
        let _ = writeln!(md, "# Terrain identification (SPEC S7)\n");
        let _ = writeln!(
            md,
            "Input `{}`: {} flat and {} rough series, first {} ticks of each dropped; rolling {} of sin θx {}; \
             {}-component Gaussian mixture over {} by EM (seed {}){}, components by ascending mean (first = flat).\n",
            self.input,
            self.series.flat,
            self.series.rough,
            self.warmup_ticks,
            self.std,
            match self.signal {
                AttitudeSource::Truth => "from the simulator's pose",
                AttitudeSource::Imu => "from the IMU's orientation filter",
            },
            self.components,
            match self.windows.first().map(|w| w.feature) {
                Some(MixtureFeature::LogStd) => {
                    "the log of each window's std (`estimator.feature = \"log-std\"`; each component's \
                     mean (std) below is its log-normal's)"
                }
                _ => "each window's std",
            },
            self.seed,
            if self.equal_weights {
                ", mixing weights held equal (`estimator.equal-weights`)"
            } else {
                ""
            }
        );
    }

    /// Table 3: each window's components and accuracy beside the paper's.
    fn write_table_3(&self, md: &mut String) {
        let _ = writeln!(
            md,
            "| window | flat mean (std) / rough mean (std) | accuracy | n | stationary, left out | paper: flat / rough | paper accuracy |"
        );
        let _ = writeln!(md, "|---:|---|---:|---:|---:|---|---:|");
        for r in &self.windows {
            let paper = PAPER_TABLE_3.iter().find(|p| p.window == r.window);
            let (paper_cell, paper_acc) =
                paper.map_or(("—".to_string(), "—".to_string()), |p| {
                    (
                        format!(
                            "{:.2} ({:.2}) / {:.2} ({:.2})",
                            p.flat_mean, p.flat_std, p.rough_mean, p.rough_std
                        ),
                        format!("{:.2} %", p.accuracy_pct),
                    )
                });
            let _ = writeln!(
                md,
                "| {} | {} | {:.2} % | {} | {} | {paper_cell} | {paper_acc} |",
                r.window,
                components_cell(r),
                100.0 * r.accuracy,
                r.n,
                r.stationary
            );
        }
    }

    /// Each window's confusion matrix, true area by class.
    fn write_confusions(&self, md: &mut String) {
        let _ = writeln!(
            md,
            "\n## Confusion matrices (rows: true area; columns: class)\n"
        );
        for r in &self.windows {
            let classes = r.means.len();
            let _ = writeln!(md, "Window {}:\n", r.window);
            let header: Vec<String> = (0..classes).map(|k| format!("class {k}")).collect();
            let _ = writeln!(md, "| true \\ predicted | {} |", header.join(" | "));
            let _ = writeln!(md, "|---|{}", "---:|".repeat(classes));
            for (area, row) in AREAS.iter().zip(&r.confusion) {
                let cells: Vec<String> = row.iter().map(u64::to_string).collect();
                let _ = writeln!(md, "| {} | {} |", area.name(), cells.join(" | "));
            }
            let _ = writeln!(md);
        }
    }

    /// The figures written beside the report, as images.
    fn write_figures(&self, md: &mut String) {
        if !self.figures.is_empty() {
            let _ = writeln!(md, "## Figures\n");
            for f in &self.figures {
                let _ = writeln!(md, "![{f}]({f})");
            }
        }
    }
}

fn delay_cell(s: &ClassifierScore) -> String {
    let d = &s.delay;
    match (d.mean, d.median) {
        (Some(mean), Some(median)) => {
            format!("{mean:.1} / {median:.1} ({}/{})", d.detected, d.changes)
        }
        _ => format!("— ({}/{})", d.detected, d.changes),
    }
}

impl OnlineReport {
    /// One row per window: accuracy and delay with and without the HMM filter.
    pub fn to_markdown(&self) -> String {
        let mut md = String::new();
        let _ = writeln!(md, "# Online terrain estimation\n");
        let _ = writeln!(
            md,
            "Input `{}`{}; a change is detected when the class holds the new area for {} ticks. \
             Delay: mean / median ticks (detected/changes).\n",
            self.input,
            if self.splice {
                ", series spliced into alternating-area streams"
            } else {
                ""
            },
            self.hold
        );
        let _ = writeln!(
            md,
            "| window | stay prob | classified | accuracy (HMM) | accuracy (raw) | delay (HMM) | delay (raw) | fits (failed) | stationary windows |"
        );
        let _ = writeln!(md, "|---:|---:|---:|---:|---:|---|---|---:|---:|");
        for e in &self.windows {
            let _ = writeln!(
                md,
                "| {} | {} | {}/{} | {:.2} % | {:.2} % | {} | {} | {} ({}) | {} |",
                e.window,
                e.stay_prob,
                e.classified,
                e.ticks,
                100.0 * e.filtered.accuracy,
                100.0 * e.raw.accuracy,
                delay_cell(&e.filtered),
                delay_cell(&e.raw),
                e.fits,
                e.failed_fits,
                e.stationary
            );
        }
        md
    }
}
