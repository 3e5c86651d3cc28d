//! How well the online estimator would have done on recorded telemetry: accuracy against the
//! window size, and the delay (ticks) from a terrain change to its detection.
//!
//! The series (SPEC S7 split, warm-up dropped) are arranged into streams, one per env, and fed
//! tick by tick, all streams in lockstep, to a cold-started [`OnlineEstimator`]. A terrain
//! change is a boundary between two consecutive series of one stream with different areas.
//! Recordings like the paper's never change area within an env, so `splice` builds changes:
//! stream `i` is `a_i, b_i, a_{i+1}` where `a`/`b` alternate between the flat and rough series
//! lists (even streams start flat, odd ones rough, so the pool sees both terrains early).

use crate::analysis::{Series, area_of_class};
use crate::online::OnlineEstimator;
use crate::{EstimatorError, Result};
use common::AreaKind;
use common::config::EstimatorConfig;
use serde::Serialize;

/// Detection delays of one classifier over every terrain change.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DelayStats {
    pub changes: usize,
    pub detected: usize,
    pub mean: Option<f64>,
    pub median: Option<f64>,
    pub max: Option<usize>,
}

/// Accuracy and delays of one classifier (filtered or raw).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassifierScore {
    /// Fraction of classified ticks whose class matches the true area.
    pub accuracy: f64,
    pub delay: DelayStats,
}

/// The online evaluation of one window size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OnlineEval {
    pub window: usize,
    pub stay_prob: f64,
    /// Ticks fed (all streams).
    pub ticks: usize,
    /// Ticks that got a class (window full and a mixture fitted).
    pub classified: usize,
    /// With the HMM filter (equals `raw` when `stay_prob` is 0).
    pub filtered: ClassifierScore,
    /// The mixture's maximum posterior alone.
    pub raw: ClassifierScore,
    pub fits: u64,
    pub failed_fits: u64,
    /// Full windows left out as stationary (the env kept its estimate).
    pub stationary: u64,
}

/// One env's input: values, true areas, and where each segment starts.
#[derive(Debug, Clone, Default)]
struct Stream {
    values: Vec<f64>,
    xz: Vec<[f64; 2]>,
    areas: Vec<AreaKind>,
    starts: Vec<usize>,
}

impl Stream {
    fn push(&mut self, s: &Series) {
        self.starts.push(self.values.len());
        self.values.extend_from_slice(&s.sin_pitch);
        self.xz.extend_from_slice(&s.xz);
        self.areas
            .extend(std::iter::repeat_n(s.area, s.sin_pitch.len()));
    }

    /// `(start, end)` of each segment that begins with a change of area.
    fn changes(&self) -> Vec<(usize, usize)> {
        let ends = self
            .starts
            .iter()
            .skip(1)
            .copied()
            .chain([self.values.len()]);
        self.starts
            .iter()
            .zip(ends)
            .filter(|&(&start, _)| start > 0 && self.areas[start] != self.areas[start - 1])
            .map(|(&start, end)| (start, end))
            .collect()
    }
}

fn build_streams(series: &[Series], splice: bool) -> Vec<Stream> {
    let (flat, rough): (Vec<&Series>, Vec<&Series>) =
        series.iter().partition(|s| s.area == AreaKind::Flat);
    if !splice || flat.is_empty() || rough.is_empty() {
        let mut by_env: std::collections::BTreeMap<u32, Stream> =
            std::collections::BTreeMap::default();
        for s in series {
            by_env.entry(s.env).or_default().push(s);
        }
        return by_env.into_values().collect();
    }
    (0..flat.len().min(rough.len()))
        .map(|i| {
            let (a, b) = if i % 2 == 0 {
                (&flat, &rough)
            } else {
                (&rough, &flat)
            };
            let mut stream = Stream::default();
            for s in [a[i], b[i], a[(i + 1) % a.len()]] {
                stream.push(s);
            }
            stream
        })
        .collect()
}

/// Runs the online estimator with window `window` (other settings from `cfg`) over the
/// series, with the runtime's stationary gate (`min_step_travel` metres per tick, 0: none).
/// A change counts as detected at the first tick from which the class stays on the new area
/// for `hold` ticks within the segment; the delay is that tick minus the change's.
pub fn evaluate_online(
    series: &[Series],
    cfg: &EstimatorConfig,
    window: usize,
    seed: u64,
    splice: bool,
    hold: usize,
    min_step_travel: f64,
) -> Result<OnlineEval> {
    if series.is_empty() {
        return Err(EstimatorError::NoWindows { window, longest: 0 });
    }
    let streams = build_streams(series, splice);
    let cfg = EstimatorConfig {
        online_window: window,
        ..cfg.clone()
    };
    let mut est = OnlineEstimator::new(&cfg, streams.len(), seed)?.gate_stationary(min_step_travel);
    // classes[stream][tick] = (filtered, raw)
    let mut classes: Vec<Vec<(Option<usize>, Option<usize>)>> = streams
        .iter()
        .map(|s| Vec::with_capacity(s.values.len()))
        .collect();
    let longest = streams.iter().map(|s| s.values.len()).max().unwrap_or(0);
    for t in 0..longest {
        for (i, stream) in streams.iter().enumerate() {
            if let Some(&x) = stream.values.get(t) {
                let e = est.observe_at(i, x, stream.xz.get(t).copied())?;
                classes[i].push((e.class, e.raw_class));
            }
        }
    }
    let pick_filtered = |c: &(Option<usize>, Option<usize>)| c.0;
    let pick_raw = |c: &(Option<usize>, Option<usize>)| c.1;
    let stats = est.stats();
    let ticks = streams.iter().map(|s| s.values.len()).sum();
    let classified = classes.iter().flatten().filter(|c| c.0.is_some()).count();
    Ok(OnlineEval {
        window,
        stay_prob: cfg.stay_prob,
        ticks,
        classified,
        filtered: score_classifier(&streams, &classes, pick_filtered, hold),
        raw: score_classifier(&streams, &classes, pick_raw, hold),
        fits: stats.fits,
        failed_fits: stats.failed_fits,
        stationary: stats.stationary,
    })
}

fn score_classifier<F>(
    streams: &[Stream],
    classes: &[Vec<(Option<usize>, Option<usize>)>],
    pick: F,
    hold: usize,
) -> ClassifierScore
where
    F: Fn(&(Option<usize>, Option<usize>)) -> Option<usize>,
{
    let (mut correct, mut classified) = (0usize, 0usize);
    let mut delays = Vec::new();
    let mut changes = 0;
    for (stream, cls) in streams.iter().zip(classes) {
        let mapped: Vec<Option<AreaKind>> =
            cls.iter().map(|c| pick(c).map(area_of_class)).collect();
        for (m, area) in mapped.iter().zip(&stream.areas) {
            if let Some(m) = m {
                classified += 1;
                correct += usize::from(m == area);
            }
        }
        for (start, end) in stream.changes() {
            changes += 1;
            let target = Some(stream.areas[start]);
            let need = hold.max(1);
            let found = (start..end.saturating_sub(need - 1))
                .find(|&t| mapped[t..t + need].iter().all(|m| *m == target));
            if let Some(t) = found {
                delays.push(t - start);
            }
        }
    }
    ClassifierScore {
        accuracy: correct as f64 / classified.max(1) as f64,
        delay: delay_stats(changes, delays),
    }
}

fn delay_stats(changes: usize, mut delays: Vec<usize>) -> DelayStats {
    delays.sort_unstable();
    let n = delays.len();
    let median = match n {
        0 => None,
        _ if n % 2 == 1 => Some(delays[n / 2] as f64),
        _ => Some((delays[n / 2 - 1] + delays[n / 2]) as f64 / 2.0),
    };
    DelayStats {
        changes,
        detected: n,
        mean: (n > 0).then(|| delays.iter().sum::<usize>() as f64 / n as f64),
        median,
        max: delays.last().copied(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(env: u32, area: AreaKind, sd: f64, n: usize, rng: &mut common::Rng) -> Series {
        Series {
            env,
            area,
            first_tick: 0,
            sin_pitch: (0..n).map(|_| sd * rng.normal()).collect(),
            sin_roll: vec![0.0; n],
            xz: vec![[0.0; 2]; n],
            command: vec![0.0; n],
        }
    }

    #[test]
    fn delay_statistics_by_hand() {
        let d = delay_stats(4, vec![7, 3, 10]);
        assert_eq!((d.changes, d.detected, d.max), (4, 3, Some(10)));
        assert_eq!(d.median, Some(7.0));
        assert!((d.mean.expect("mean") - 20.0 / 3.0).abs() < 1e-12);
        assert_eq!(delay_stats(2, vec![]).mean, None);
        assert_eq!(delay_stats(2, vec![1, 4]).median, Some(2.5));
    }

    #[test]
    fn splicing_builds_alternating_streams_with_changes() {
        let mut rng = common::Rng::new(1);
        let s = vec![
            series(0, AreaKind::Flat, 0.02, 10, &mut rng),
            series(1, AreaKind::Flat, 0.02, 10, &mut rng),
            series(2, AreaKind::Rough, 0.08, 10, &mut rng),
            series(3, AreaKind::Rough, 0.08, 10, &mut rng),
        ];
        let streams = build_streams(&s, true);
        assert_eq!(streams.len(), 2);
        assert_eq!(streams[0].changes(), vec![(10, 20), (20, 30)]);
        assert_eq!(streams[0].areas[0], AreaKind::Flat);
        assert_eq!(streams[1].areas[0], AreaKind::Rough);
        assert!(
            build_streams(&s, false)
                .iter()
                .all(|st| st.changes().is_empty())
        );
    }

    #[test]
    fn online_evaluation_detects_changes_and_longer_windows_are_more_accurate() {
        let mut rng = common::Rng::new(2);
        let mut s = Vec::new();
        for env in 0..4 {
            s.push(series(env, AreaKind::Flat, 0.02, 400, &mut rng));
            s.push(series(env + 4, AreaKind::Rough, 0.06, 400, &mut rng));
        }
        let cfg = EstimatorConfig {
            refit_every: 100,
            ..EstimatorConfig::default()
        };
        let short = evaluate_online(&s, &cfg, 5, 1, true, 5, 0.0).expect("w5");
        let long = evaluate_online(&s, &cfg, 40, 1, true, 5, 0.0).expect("w40");
        assert_eq!(long.filtered.delay.changes, 8);
        assert_eq!(long.filtered.delay.detected, 8, "{long:?}");
        assert!(
            long.raw.accuracy > short.raw.accuracy,
            "{} vs {}",
            long.raw.accuracy,
            short.raw.accuracy
        );
        assert!(long.filtered.accuracy > 0.9, "{long:?}");
        // The delay is bounded by about one window: the window must fill with the new terrain.
        let mean = long.filtered.delay.mean.expect("detected");
        assert!(mean > 5.0 && mean < 60.0, "{mean}");
        assert_eq!(long.ticks, 4 * 1200);
    }
}
