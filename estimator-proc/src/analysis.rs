//! The paper's offline terrain-identification experiment (SPEC S7) on recorded telemetry.
//!
//! 1. Split the rows into series: one per env, and a new one whenever an env's area changes or
//!    its tick does not follow the previous one (a gap or a restarted recording).
//! 2. Drop the first `warmup-ticks` of each series (SPEC S7 step 1).
//! 3. Rolling sample std of sin θx within each series, full windows only, so no window spans
//!    two series (step 2). **(interpretation)** The warm-up is dropped before the rolling std,
//!    as the paper discards those steps from the data; each series then yields
//!    `len − w + 1` values.
//! 4. Pool every series' values, fit the mixture unsupervised, label by ascending mean, and
//!    only then score against the true area labels (steps 3–4).

use crate::gmm::{self, FitOptions, Gmm};
use crate::rolling::{Ddof, rolling_path, rolling_std};
use crate::{EstimatorError, Result};
use common::config::MixtureFeature;
use common::{AreaKind, TelemetryRow};
use serde::Serialize;
use std::collections::BTreeMap;

/// The window of the std-distribution figure (SPEC S7 step 2, paper Fig. 7).
pub const DISTRIBUTION_WINDOW: usize = 100;
/// The windows of the confusion heatmaps (SPEC S7 step 4, paper Fig. 8).
pub const HEATMAP_WINDOWS: [usize; 2] = [10, 70];
/// The std convention of the paper's pandas analysis (`rolling(w).std()`, SPEC S7).
pub const DDOF: Ddof = Ddof::Sample;

/// Both areas in their code order (flat = 0, rough = 1): the confusion matrices' rows.
pub const AREAS: [AreaKind; 2] = [AreaKind::Flat, AreaKind::Rough];

/// One row of the paper's Table 3 (SPEC S7).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperRow {
    pub window: usize,
    pub flat_mean: f64,
    pub flat_std: f64,
    pub rough_mean: f64,
    pub rough_std: f64,
    pub accuracy_pct: f64,
}

/// The paper's Table 3, to print beside ours (SPEC S7).
pub const PAPER_TABLE_3: [PaperRow; 4] = [
    PaperRow {
        window: 10,
        flat_mean: 0.02,
        flat_std: 0.01,
        rough_mean: 0.08,
        rough_std: 0.04,
        accuracy_pct: 61.13,
    },
    PaperRow {
        window: 20,
        flat_mean: 0.03,
        flat_std: 0.01,
        rough_mean: 0.08,
        rough_std: 0.03,
        accuracy_pct: 70.73,
    },
    PaperRow {
        window: 40,
        flat_mean: 0.05,
        flat_std: 0.01,
        rough_mean: 0.11,
        rough_std: 0.07,
        accuracy_pct: 85.87,
    },
    PaperRow {
        window: 70,
        flat_mean: 0.05,
        flat_std: 0.01,
        rough_mean: 0.11,
        rough_std: 0.03,
        accuracy_pct: 98.79,
    },
];

/// One contiguous run of one env on one area, warm-up already dropped.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub env: u32,
    pub area: AreaKind,
    /// Tick of the first kept value.
    pub first_tick: u64,
    pub sin_pitch: Vec<f64>,
    /// sin θz (roll), for the time-series figure.
    pub sin_roll: Vec<f64>,
    /// The robot's X-Z position, metres, for the stationary gate (`estimator.min-speed`).
    pub xz: Vec<[f64; 2]>,
    /// The wheels' mean command, rad/s, for the slip feature.
    pub command: Vec<f64>,
}

/// Splits rows (any interleaving of envs) into series and drops each one's first `warmup`
/// ticks (SPEC S7 step 1). Series emptied by the warm-up are dropped; the rest are ordered by
/// env, then first tick.
pub fn split_series(rows: &[TelemetryRow], warmup: usize) -> Vec<Series> {
    // SPEC S7 step 1: series per env and area, warm-up dropped per series.
    let mut open: BTreeMap<u32, (u64, Series)> = BTreeMap::new();
    let mut done = Vec::new();
    for row in rows {
        let continues = open
            .get(&row.env)
            .is_some_and(|(last, s)| s.area == row.area && row.tick == last.wrapping_add(1));
        if !continues {
            let fresh = Series {
                env: row.env,
                area: row.area,
                first_tick: row.tick,
                sin_pitch: Vec::new(),
                sin_roll: Vec::new(),
                xz: Vec::new(),
                command: Vec::new(),
            };
            if let Some((_, finished)) = open.insert(row.env, (row.tick, fresh)) {
                done.push(finished);
            }
        }
        if let Some((last, s)) = open.get_mut(&row.env) {
            *last = row.tick;
            s.sin_pitch.push(row.sin_pitch);
            s.sin_roll.push(row.theta_z.sin());
            s.xz.push([row.x, row.z]);
            s.command.push(0.5 * (row.action_left + row.action_right));
        }
    }
    done.extend(open.into_values().map(|(_, s)| s));
    let mut kept: Vec<Series> = done
        .into_iter()
        .filter(|s| s.sin_pitch.len() > warmup)
        .map(|mut s| {
            s.first_tick += warmup as u64;
            s.sin_pitch.drain(..warmup);
            s.sin_roll.drain(..warmup);
            s.xz.drain(..warmup);
            s.command.drain(..warmup);
            s
        })
        .collect();
    kept.sort_by_key(|s| (s.env, s.first_tick));
    kept
}

/// Pooled rolling-std values of every series and their true areas (SPEC S7 step 2).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WindowValues {
    pub window: usize,
    pub values: Vec<f64>,
    pub areas: Vec<AreaKind>,
    /// Windows left out as stationary.
    pub stationary: usize,
}

impl WindowValues {
    /// The values whose true area is `area`.
    pub fn of(&self, area: AreaKind) -> Vec<f64> {
        self.values
            .iter()
            .zip(&self.areas)
            .filter(|(_, a)| **a == area)
            .map(|(v, _)| *v)
            .collect()
    }
}

/// Rolling std of sin θx within each series (no window spans two series), pooled.
///
/// Windows whose path is shorter than `min_step_travel` metres per step are left out and
/// counted in [`WindowValues::stationary`] (`estimator.min-speed`; 0 keeps all, as the paper).
pub fn window_values(
    series: &[Series],
    window: usize,
    min_step_travel: f64,
) -> Result<WindowValues> {
    let mut out = WindowValues {
        window,
        ..WindowValues::default()
    };
    let min_travel = min_step_travel * (window - 1) as f64;
    // SPEC S7 step 2: each series rolled on its own, then pooled.
    for s in series {
        let v = rolling_std(&s.sin_pitch, window, DDOF)?;
        let path = rolling_path(&s.xz, window)?;
        for (x, travelled) in v.into_iter().zip(path) {
            if travelled >= min_travel {
                out.values.push(x);
                out.areas.push(s.area);
            } else {
                out.stationary += 1;
            }
        }
    }
    if out.values.is_empty() && out.stationary > 0 {
        return Err(EstimatorError::AllStationary {
            window,
            stationary: out.stationary,
        });
    }
    if out.values.is_empty() {
        return Err(EstimatorError::NoWindows {
            window,
            longest: series.iter().map(|s| s.sin_pitch.len()).max().unwrap_or(0),
        });
    }
    Ok(out)
}

/// The area a mixture component stands for: SPEC S7 names the lowest-mean component "flat";
/// with more than two components every other one counts as "rough" when scoring.
pub fn area_of_class(class: usize) -> AreaKind {
    if class == 0 {
        AreaKind::Flat
    } else {
        AreaKind::Rough
    }
}

/// The fit and score of one window size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WindowResult {
    pub window: usize,
    /// What the mixture was fitted on (`estimator.feature`); its parameters are over it.
    pub feature: MixtureFeature,
    /// Pooled values fitted (both areas).
    pub n: usize,
    /// Windows left out as stationary (`estimator.min-speed`).
    pub stationary: usize,
    pub n_flat: usize,
    pub n_rough: usize,
    /// Mixture parameters, components by ascending mean (0 = flat).
    pub weights: Vec<f64>,
    pub means: Vec<f64>,
    pub stds: Vec<f64>,
    pub log_likelihood: f64,
    pub iterations: usize,
    pub converged: bool,
    /// Fraction of values whose class ([`area_of_class`]) equals the true area.
    pub accuracy: f64,
    /// `confusion[a][k]`: values of true area `a` (0 flat, 1 rough) put in component `k`.
    pub confusion: Vec<Vec<u64>>,
}

/// Counts `confusion[area][class]` and the accuracy of `model`'s classes on `values`.
pub fn score(model: &Gmm, values: &[f64], areas: &[AreaKind]) -> (f64, Vec<Vec<u64>>) {
    let mut confusion = vec![vec![0u64; model.components()]; AREAS.len()];
    let mut correct = 0usize;
    for (&x, &area) in values.iter().zip(areas) {
        let class = model.classify(x);
        confusion[usize::from(area.code())][class] += 1;
        correct += usize::from(area_of_class(class) == area);
    }
    (correct as f64 / values.len().max(1) as f64, confusion)
}

impl WindowResult {
    /// Each component's mean and std in units of the window std, for Table 3: the fit's own
    /// over `std`; over `log-std`, those of the log-normal it stands for.
    pub fn components_in_std(&self) -> Vec<(f64, f64)> {
        self.means
            .iter()
            .zip(&self.stds)
            .map(|(&m, &s)| match self.feature {
                MixtureFeature::Std => (m, s),
                MixtureFeature::LogStd => {
                    let mean = (m + 0.5 * s * s).exp();
                    (mean, mean * (s * s).exp_m1().sqrt())
                }
            })
            .collect()
    }
}

/// Fits and scores one window size (SPEC S7 steps 2–4) over `feature` of each window's std.
/// The labels are used only by `score`, after the fit.
pub fn analyze_window(
    series: &[Series],
    window: usize,
    opts: &FitOptions,
    min_step_travel: f64,
    feature: MixtureFeature,
) -> Result<WindowResult> {
    let wv = window_values(series, window, min_step_travel)?;
    let values: Vec<f64> = wv.values.iter().map(|&v| feature.of(v)).collect();
    // SPEC S7 step 3: unsupervised, the fit sees the values only.
    let report = gmm::fit(&values, opts)?;
    let (accuracy, confusion) = score(&report.model, &values, &wv.areas);
    let m = &report.model;
    Ok(WindowResult {
        window,
        feature,
        n: wv.values.len(),
        stationary: wv.stationary,
        n_flat: wv.areas.iter().filter(|a| **a == AreaKind::Flat).count(),
        n_rough: wv.areas.iter().filter(|a| **a == AreaKind::Rough).count(),
        weights: m.weights().to_vec(),
        means: m.means().to_vec(),
        stds: m.stds(),
        log_likelihood: report.log_likelihood,
        iterations: report.iterations,
        converged: report.converged,
        accuracy,
        confusion,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(env: u32, tick: u64, area: AreaKind, sin_pitch: f64) -> TelemetryRow {
        TelemetryRow {
            env,
            tick,
            area,
            theta_x: sin_pitch.asin(),
            sin_pitch,
            ..TelemetryRow::default()
        }
    }

    #[test]
    fn spec_s7_series_split_on_env_area_and_tick_gaps_then_warmup_dropped() {
        use AreaKind::{Flat, Rough};
        // Interleaved envs; env 0 moves to rough at tick 6; env 1 has a gap after tick 3.
        let mut rows = Vec::new();
        for t in 0..10u64 {
            rows.push(row(0, t, if t < 6 { Flat } else { Rough }, t as f64 * 0.01));
            if t != 4 {
                rows.push(row(1, t, Flat, 0.5));
            }
        }
        let s = split_series(&rows, 2);
        let summary: Vec<(u32, AreaKind, u64, usize)> = s
            .iter()
            .map(|s| (s.env, s.area, s.first_tick, s.sin_pitch.len()))
            .collect();
        assert_eq!(
            summary,
            vec![
                (0, Flat, 2, 4),
                (0, Rough, 8, 2),
                (1, Flat, 2, 2),
                (1, Flat, 7, 3)
            ]
        );
        assert_eq!(s[0].sin_pitch, vec![0.02, 0.03, 0.04, 0.05]);
        // A series no longer than the warm-up disappears.
        assert_eq!(split_series(&rows, 6).len(), 0);
    }

    #[test]
    fn spec_s7_no_window_spans_two_series() {
        let series = vec![
            Series {
                env: 0,
                area: AreaKind::Flat,
                first_tick: 0,
                sin_pitch: vec![0.0, 0.0, 0.0],
                sin_roll: vec![0.0; 3],
                xz: vec![[0.0; 2]; 3],
                command: vec![0.0; 3],
            },
            Series {
                env: 0,
                area: AreaKind::Rough,
                first_tick: 3,
                sin_pitch: vec![1.0, 1.0, 1.0],
                sin_roll: vec![0.0; 3],
                xz: vec![[0.0; 2]; 3],
                command: vec![0.0; 3],
            },
        ];
        // Windows of 2 inside each constant series: all zero; a spanning window would be 0.707.
        let wv = window_values(&series, 2, 0.0).expect("values");
        assert_eq!(wv.values, vec![0.0; 4]);
        assert_eq!(
            wv.areas,
            vec![
                AreaKind::Flat,
                AreaKind::Flat,
                AreaKind::Rough,
                AreaKind::Rough
            ]
        );
        assert!(matches!(
            window_values(&series, 4, 0.0),
            Err(EstimatorError::NoWindows {
                window: 4,
                longest: 3
            })
        ));
    }

    #[test]
    fn stationary_windows_are_left_out_and_counted() {
        // 6 ticks: driving 1 cm per tick for 3 ticks, then standing still.
        let s = Series {
            env: 0,
            area: AreaKind::Rough,
            first_tick: 0,
            sin_pitch: vec![0.0, 0.1, 0.0, 0.1, 0.1, 0.1],
            sin_roll: vec![0.0; 6],
            xz: [0.0, 0.01, 0.02, 0.03, 0.03, 0.03]
                .map(|x| [x, 0.0])
                .to_vec(),
            command: vec![0.0; 6],
        };
        // Windows of 3: paths 2, 2, 1, 0 cm. A 0.75 cm/step gate needs 1.5 cm.
        let wv = window_values(std::slice::from_ref(&s), 3, 0.0075).expect("values");
        assert_eq!((wv.values.len(), wv.stationary), (2, 2));
        assert_eq!(
            window_values(std::slice::from_ref(&s), 3, 0.0)
                .expect("all")
                .values
                .len(),
            4
        );
        let still = Series {
            xz: vec![[0.0; 2]; 6],
            command: vec![0.0; 6],
            ..s
        };
        assert!(matches!(
            window_values(&[still], 3, 0.0075),
            Err(EstimatorError::AllStationary {
                window: 3,
                stationary: 4
            })
        ));
    }

    #[test]
    fn spec_s7_lowest_mean_is_flat_and_scoring_counts_confusion() {
        let model = Gmm::new(vec![0.5, 0.5], vec![0.08, 0.02], vec![1e-4, 1e-4]).expect("model");
        let values = [0.01, 0.03, 0.09, 0.02, 0.10];
        use AreaKind::{Flat, Rough};
        let (acc, conf) = score(&model, &values, &[Flat, Flat, Rough, Rough, Rough]);
        assert_eq!(conf, vec![vec![2, 0], vec![1, 2]]);
        assert!((acc - 0.8).abs() < 1e-12);
        assert_eq!(area_of_class(0), Flat);
        assert_eq!(area_of_class(2), Rough);
    }

    /// Rough ground whose bumpiness varies from stretch to stretch gives window stds skewed
    /// to the right: one Gaussian stretched over them takes in flat windows, which the fit
    /// over log std leaves alone.
    #[test]
    fn a_fit_over_log_std_copes_with_skewed_rough_windows() {
        let mut rng = common::Rng::new(3);
        let mut rows = Vec::new();
        for env in 0..8u32 {
            let area = if env < 4 {
                AreaKind::Flat
            } else {
                AreaKind::Rough
            };
            let mut amplitude = 0.02;
            for tick in 0..600 {
                if area == AreaKind::Rough && tick % 20 == 0 {
                    amplitude = 0.06 * (1.3 * rng.normal()).exp();
                }
                rows.push(row(env, tick, area, amplitude * rng.normal()));
            }
        }
        let series = split_series(&rows, 0);
        let opts = FitOptions::from_config(&common::config::EstimatorConfig::default(), 1);
        let fit = |feature| analyze_window(&series, 20, &opts, 0.0, feature).expect("fit");
        let (std, log) = (fit(MixtureFeature::Std), fit(MixtureFeature::LogStd));
        assert_eq!(
            (std.feature, log.feature),
            (MixtureFeature::Std, MixtureFeature::LogStd)
        );
        assert!(
            log.accuracy > std.accuracy + 0.01 && log.accuracy > 0.93,
            "log std {} vs std {}",
            log.accuracy,
            std.accuracy
        );
        // Table 3 shows the log fit's components as the log-normals they stand for.
        let (mean, sd) = log.components_in_std()[0];
        let (m, s) = (log.means[0], log.stds[0]);
        assert!((mean - (m + s * s / 2.0).exp()).abs() < 1e-12);
        assert!((sd - mean * ((s * s).exp() - 1.0).sqrt()).abs() < 1e-12);
        assert!((0.01..0.03).contains(&mean), "flat component at {mean}");
    }

    #[test]
    fn spec_s7_paper_table_is_the_papers() {
        let windows: Vec<usize> = PAPER_TABLE_3.iter().map(|r| r.window).collect();
        assert_eq!(windows, vec![10, 20, 40, 70]);
        assert_eq!(PAPER_TABLE_3[3].accuracy_pct, 98.79);
        assert_eq!(HEATMAP_WINDOWS, [10, 70]);
        assert_eq!(DISTRIBUTION_WINDOW, 100);
        assert_eq!(DDOF, Ddof::Sample);
    }
}
