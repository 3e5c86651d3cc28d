//! Running observation normalisation (mean and population variance per feature).
//!
//! Statistics are accumulated in f64 (Chan et al.'s parallel update, as gym's
//! `RunningMeanStd`) and shipped as f32 in the flat policy vector, where the simulator
//! applies `clamp((x − mean) / sqrt(var + 1e-8), ±obs_clip)` (`common::policy`). The learner
//! normalises with exactly that f32 formula, so both sides see the same network input.

use common::policy::OBS_NORM_EPS;
use serde::{Deserialize, Serialize};

/// Per-feature running mean and variance over every observation seen so far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    pub mean: Vec<f64>,
    pub var: Vec<f64>,
    /// Observations absorbed, plus gym's 1e-4 pseudo-count (so the first batch dominates
    /// the initial mean 0, variance 1 without dividing by zero).
    pub count: f64,
}

impl RunningMeanStd {
    pub fn new(dim: usize) -> Self {
        Self {
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            count: 1e-4,
        }
    }

    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Absorbs a batch of observations, `rows` of `dim` features each.
    pub fn update<'a>(&mut self, rows: impl ExactSizeIterator<Item = &'a [f32]> + Clone) {
        let n = rows.len();
        if n == 0 {
            return;
        }
        let dim = self.dim();
        let mut batch_mean = vec![0.0f64; dim];
        for row in rows.clone() {
            for (m, &x) in batch_mean.iter_mut().zip(row) {
                *m += f64::from(x);
            }
        }
        batch_mean.iter_mut().for_each(|m| *m /= n as f64);
        let mut batch_var = vec![0.0f64; dim];
        for row in rows {
            for ((v, &x), m) in batch_var.iter_mut().zip(row).zip(&batch_mean) {
                *v += (f64::from(x) - m).powi(2);
            }
        }
        batch_var.iter_mut().for_each(|v| *v /= n as f64);

        let batch_count = n as f64;
        let total = self.count + batch_count;
        for i in 0..dim {
            let delta = batch_mean[i] - self.mean[i];
            let m2 = self.var[i] * self.count
                + batch_var[i] * batch_count
                + delta * delta * self.count * batch_count / total;
            self.mean[i] += delta * batch_count / total;
            self.var[i] = m2 / total;
        }
        self.count = total;
    }

    /// The f32 statistics as shipped in the policy vector: `(mean, var)`.
    pub fn shipped(&self) -> (Vec<f32>, Vec<f32>) {
        (
            self.mean.iter().map(|&m| m as f32).collect(),
            self.var.iter().map(|&v| v as f32).collect(),
        )
    }
}

/// Normalises, in place with shipped f32 statistics, the first `mean.len()` features of each
/// `stride`-wide row of `rows`.
pub fn normalise(rows: &mut [f32], stride: usize, mean: &[f32], var: &[f32], clip: f32) {
    let scale: Vec<f32> = var.iter().map(|v| (v + OBS_NORM_EPS).sqrt()).collect();
    for row in rows.chunks_exact_mut(stride) {
        for ((x, m), s) in row.iter_mut().zip(mean).zip(&scale) {
            *x = ((*x - m) / s).clamp(-clip, clip);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::Rng;

    /// Streaming over uneven batches equals a naive two-pass computation over all data plus
    /// the prior pseudo-observation (weight 1e-4, mean 0, variance 1).
    #[test]
    fn running_stats_match_a_naive_computation() {
        let mut rng = Rng::new(5);
        let data: Vec<[f32; 3]> = (0..1000)
            .map(|_| {
                [
                    rng.range(-1.0, 3.0) as f32,
                    (10.0 + 5.0 * rng.normal()) as f32,
                    100.0 + rng.normal() as f32,
                ]
            })
            .collect();
        let mut rms = RunningMeanStd::new(3);
        let mut at = 0;
        for size in [1, 7, 100, 392, 500] {
            rms.update(data[at..at + size].iter().map(<[f32; 3]>::as_slice));
            at += size;
        }
        assert_eq!(at, data.len());
        let prior = 1e-4;
        let total = data.len() as f64 + prior;
        for j in 0..3 {
            let mean = data.iter().map(|r| f64::from(r[j])).sum::<f64>() / total;
            let m2 = data
                .iter()
                .map(|r| (f64::from(r[j]) - mean).powi(2))
                .sum::<f64>();
            let var = (m2 + prior * (1.0 + mean * mean)) / total;
            assert!(
                (rms.mean[j] - mean).abs() <= 1e-10 * mean.abs().max(1.0),
                "mean {j}"
            );
            assert!(
                (rms.var[j] - var).abs() <= 1e-9 * var,
                "var {j}: {} vs {var}",
                rms.var[j]
            );
        }
        assert!((rms.count - total).abs() < 1e-9);
    }

    #[test]
    fn normalise_uses_the_policy_formula_and_clips() {
        // Two rows of two features and an untouched third column.
        let mut obs = [3.0, 1.0, 7.0, 1e6, 0.5, 7.0];
        normalise(&mut obs, 3, &[1.0, 2.0], &[4.0 - 1e-8, 1.0 - 1e-8], 5.0);
        assert!((obs[0] - 1.0).abs() < 1e-6 && (obs[1] + 1.0).abs() < 1e-6);
        assert_eq!((obs[2], obs[3], obs[5]), (7.0, 5.0, 7.0));
        assert!((obs[4] + 1.5).abs() < 1e-6);
    }
}
