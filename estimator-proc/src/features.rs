//! Several numbers per window ([`WindowFeature`]), for telling more than two terrain kinds
//! apart (SPEC S7 uses one, the std of sin θx).
//!
//! Every feature of a window ending at tick t covers ticks t − w + 1 ..= t of one series, as
//! SPEC S7's rolling std does; windows never span two series, and windows the robot barely
//! moved in are left out by the same gate (`estimator.min-speed`), unless the features hold
//! slip and the wheels were driven that far: a robot dug in, wheels turning, slip 1.

use crate::analysis::{DDOF, Series};
use crate::rolling::{rolling_path, rolling_std};
use crate::{EstimatorError, Result};
use common::AreaKind;
use common::config::WindowFeature;

/// What the slip feature needs of the robot: wheel radius (m) and decision step (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wheels {
    pub radius: f64,
    pub dt: f64,
}

impl Wheels {
    /// The path a decision step at wheel command `command` (rad/s) asks for, metres.
    pub fn rim_path(self, command: f64) -> f64 {
        command.abs() * self.radius * self.dt
    }
}

/// Every counted window's features (row-major, `dim` per window) and true kind.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureWindows {
    pub dim: usize,
    pub values: Vec<f64>,
    pub kinds: Vec<AreaKind>,
    /// Windows left out as stationary.
    pub stationary: usize,
}

impl FeatureWindows {
    pub fn len(&self) -> usize {
        self.kinds.len()
    }

    pub fn is_empty(&self) -> bool {
        self.kinds.is_empty()
    }

    /// The same windows described by the features at `keep` (indices into this one's).
    pub fn select(&self, keep: &[usize]) -> Self {
        Self {
            dim: keep.len(),
            values: self
                .values
                .chunks_exact(self.dim)
                .flat_map(|row| keep.iter().map(|&i| row[i]))
                .collect(),
            kinds: self.kinds.clone(),
            stationary: self.stationary,
        }
    }
}

/// `features` of every window of `window` ticks in `series`, pooled.
pub fn window_features(
    series: &[Series],
    window: usize,
    features: &[WindowFeature],
    min_step_travel: f64,
    wheels: Wheels,
) -> Result<FeatureWindows> {
    let mut out = FeatureWindows {
        dim: features.len(),
        ..FeatureWindows::default()
    };
    let min_travel = min_step_travel * (window - 1) as f64;
    let slip = features.contains(&WindowFeature::Slip);
    for s in series {
        let path = rolling_path(&s.xz, window)?;
        let columns: Vec<Vec<f64>> = features
            .iter()
            .map(|&f| column(s, window, f, &path, wheels))
            .collect::<Result<_>>()?;
        let driven = if slip {
            commanded_path(s, window, wheels)
        } else {
            vec![0.0; path.len()]
        };
        for (t, &travelled) in path.iter().enumerate() {
            if counts(travelled, driven[t], min_travel) {
                out.values.extend(columns.iter().map(|c| c[t]));
                out.kinds.push(s.area);
            } else {
                out.stationary += 1;
            }
        }
    }
    if out.is_empty() {
        return Err(if out.stationary > 0 {
            EstimatorError::AllStationary {
                window,
                stationary: out.stationary,
            }
        } else {
            EstimatorError::NoWindows {
                window,
                longest: series.iter().map(|s| s.sin_pitch.len()).max().unwrap_or(0),
            }
        });
    }
    Ok(out)
}

/// One feature at every full window of `s` (`path`: the rolling path, one per window).
fn column(
    s: &Series,
    w: usize,
    feature: WindowFeature,
    path: &[f64],
    wheels: Wheels,
) -> Result<Vec<f64>> {
    Ok(match feature {
        WindowFeature::PitchStd => rolling_std(&s.sin_pitch, w, DDOF)?,
        WindowFeature::RollStd => rolling_std(&s.sin_roll, w, DDOF)?,
        WindowFeature::MeanTilt => {
            let tilt: Vec<f64> = s
                .sin_pitch
                .iter()
                .zip(&s.sin_roll)
                .map(|(p, r)| tilt(*p, *r))
                .collect();
            window_sums(&tilt, 0, w)
                .into_iter()
                .map(|sum| sum / w as f64)
                .collect()
        }
        WindowFeature::PitchHighPass => {
            // Second differences at ticks 1 ..= n − 2; a window holds w − 2 of them.
            let sq: Vec<f64> = s
                .sin_pitch
                .windows(3)
                .map(|v| (v[2] - 2.0 * v[1] + v[0]).powi(2))
                .collect();
            window_sums(&sq, 2, w)
                .into_iter()
                .map(|sum| (sum / (w - 2).max(1) as f64).sqrt())
                .collect()
        }
        WindowFeature::Slip => commanded_path(s, w, wheels)
            .into_iter()
            .zip(path)
            .map(|(want, got)| slip(*got, want))
            .collect(),
    })
}

/// The path the wheels' mean command asked for in each full window: |command| · r · dt over
/// the moves into ticks t − w + 2 ..= t, as the rolling path counts them.
fn commanded_path(s: &Series, w: usize, wheels: Wheels) -> Vec<f64> {
    let commanded: Vec<f64> = s.command.iter().map(|&c| wheels.rim_path(c)).collect();
    window_sums(&commanded[1.min(commanded.len())..], 1, w)
}

/// Whether a window counts: the robot moved `min_travel`, or its wheels were driven that far
/// (`driven`, 0 unless the features hold slip).
pub fn counts(travelled: f64, driven: f64, min_travel: f64) -> bool {
    travelled >= min_travel || driven >= min_travel
}

/// The chassis's tilt from upright, radians: `acos(cos θx cos θz)` (Unity's Y-X-Z order puts
/// the body's up at `(…, cos θx cos θz, …)`), from sin θx and sin θz (|θ| < 90°).
pub fn tilt(sin_pitch: f64, sin_roll: f64) -> f64 {
    let cos = |s: f64| (1.0 - s * s).max(0.0).sqrt();
    (cos(sin_pitch) * cos(sin_roll)).clamp(-1.0, 1.0).acos()
}

/// `1 − path ÷ commanded`: 0 when the robot moved as far as its wheels turned, 1 when it
/// did not move; 0 when the wheels were not driven.
pub fn slip(path: f64, commanded: f64) -> f64 {
    if commanded > 1e-9 {
        1.0 - path / commanded
    } else {
        0.0
    }
}

/// Sums over each full window of `w` ticks of `xs`, whose element i belongs to tick
/// `i + offset` (values from a window's ticks only): one per window, `n − w + 1` of them for
/// a series of n ticks.
fn window_sums(xs: &[f64], offset: usize, w: usize) -> Vec<f64> {
    let inner = w - offset;
    let mut prefix = Vec::with_capacity(xs.len() + 1);
    prefix.push(0.0);
    for x in xs {
        prefix.push(prefix[prefix.len() - 1] + x);
    }
    (inner..=xs.len())
        .map(|end| prefix[end] - prefix[end - inner])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(
        sin_pitch: Vec<f64>,
        sin_roll: Vec<f64>,
        xz: Vec<[f64; 2]>,
        command: Vec<f64>,
    ) -> Series {
        Series {
            env: 0,
            area: AreaKind::Slope,
            first_tick: 0,
            sin_pitch,
            sin_roll,
            xz,
            command,
        }
    }

    const WHEELS: Wheels = Wheels {
        radius: 0.05,
        dt: 0.1,
    };

    #[test]
    fn each_feature_matches_its_hand_computed_value() {
        // 4 ticks, window 3: two windows (ticks 0–2 and 1–3).
        let s = series(
            vec![0.0, 0.1, 0.0, 0.3],
            vec![0.0, 0.0, 0.6, 0.0],
            vec![[0.0, 0.0], [0.01, 0.0], [0.02, 0.0], [0.02, 0.0]],
            vec![2.0, 2.0, 2.0, 2.0],
        );
        let all = [
            WindowFeature::PitchStd,
            WindowFeature::RollStd,
            WindowFeature::MeanTilt,
            WindowFeature::PitchHighPass,
            WindowFeature::Slip,
        ];
        let f = window_features(std::slice::from_ref(&s), 3, &all, 0.0, WHEELS).expect("features");
        assert_eq!((f.dim, f.len()), (5, 2));
        let row = |i: usize| &f.values[i * 5..(i + 1) * 5];
        // Pitch std of (0, 0.1, 0): mean 1/30, sample variance (2·(1/30)² + (2/30)²)/2 = 1/300.
        assert!((row(0)[0] - (1.0f64 / 300.0).sqrt()).abs() < 1e-12);
        // Roll std of (0, 0, 0.6): sample variance 0.12.
        assert!((row(0)[1] - 0.12f64.sqrt()).abs() < 1e-12);
        // Mean tilt over ticks 0–2: tilts 0, asin 0.1, asin 0.6 (one angle zero each tick).
        let want = (0.1f64.asin() + 0.6f64.asin()) / 3.0;
        assert!((row(0)[2] - want).abs() < 1e-12, "{} vs {want}", row(0)[2]);
        // High-pass: the window of ticks 0–2 holds one second difference, 0 − 0.2 + 0 = −0.2;
        // ticks 1–3: 0.3 − 0 + 0.1 = 0.4.
        assert!((row(0)[3] - 0.2).abs() < 1e-12 && (row(1)[3] - 0.4).abs() < 1e-12);
        // Slip: two moves of 2 rad/s × 0.05 m × 0.1 s = 1 cm commanded each. Ticks 0–2 moved
        // 2 cm of 2: no slip; ticks 1–3 moved 1 cm of 2: half.
        assert!(row(0)[4].abs() < 1e-12 && (row(1)[4] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_selection_keeps_the_windows_and_picks_columns() {
        let s = series(
            vec![0.0, 0.1, 0.0, 0.3],
            vec![0.0; 4],
            vec![[0.0, 0.0], [0.01, 0.0], [0.02, 0.0], [0.03, 0.0]],
            vec![1.0; 4],
        );
        let both = [WindowFeature::PitchStd, WindowFeature::Slip];
        let f = window_features(std::slice::from_ref(&s), 3, &both, 0.0, WHEELS).expect("features");
        let slip_only = f.select(&[1]);
        assert_eq!(slip_only.dim, 1);
        assert_eq!(slip_only.values, vec![f.values[1], f.values[3]]);
        assert_eq!(slip_only.kinds, f.kinds);
    }

    #[test]
    fn no_movement_is_no_slip_and_tilt_is_zero_upright() {
        assert_eq!(slip(0.0, 0.0), 0.0);
        assert_eq!(slip(0.0, 0.1), 1.0);
        assert_eq!(tilt(0.0, 0.0), 0.0);
        let t = tilt(30f64.to_radians().sin(), 0.0);
        assert!((t - 30f64.to_radians()).abs() < 1e-12);
    }
}
