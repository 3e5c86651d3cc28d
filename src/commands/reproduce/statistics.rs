//! Confidence intervals and paired comparisons of two models' legs.

use super::legs::{Legs, common_legs};
use statrs::distribution::{ContinuousCDF, StudentsT};

/// Mean and half-width of the 95 % confidence interval of the mean, with [`t975`].
pub(crate) fn mean_ci(xs: &[f64]) -> (f64, f64) {
    let n = xs.len();
    let mean = xs.iter().sum::<f64>() / n.max(1) as f64;
    if n < 2 {
        return (mean, f64::NAN);
    }
    let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    (mean, t975(n - 1) * sd / (n as f64).sqrt())
}

/// `mean ± half` of an interval with `digits` decimals: the mean alone where there is no
/// interval (one value), `-` where there is no mean (no value).
pub(crate) fn interval((mean, half): (f64, f64), digits: usize) -> String {
    match (mean.is_finite(), half.is_finite()) {
        (false, _) => "-".into(),
        (true, false) => format!("{mean:.digits$}"),
        (true, true) => format!("{mean:.digits$} ± {half:.digits$}"),
    }
}

/// [`interval`] of the mean of `xs` ([`mean_ci`]), `-` for none.
pub(crate) fn mean_pm(xs: &[f64], digits: usize) -> String {
    if xs.is_empty() {
        return "-".into();
    }
    interval(mean_ci(xs), digits)
}

/// The two-sided 95 % quantile of Student's t with `df` degrees of freedom.
fn t975(df: usize) -> f64 {
    // A standard t exists for every df >= 1, the only ones `mean_ci` asks for.
    StudentsT::new(0.0, 1.0, df as f64).map_or(f64::NAN, |t| t.inverse_cdf(0.975))
}

/// Two models `x` and `y` compared on the legs both drove (same part, env and leg index).
#[derive(Debug)]
pub(super) struct Paired {
    pub(super) legs: usize,
    /// Success % of `x` and of `y` on those legs.
    pub(super) success: [f64; 2],
    /// Legs both reached, and `x`'s and `y`'s mean reach time on them, seconds.
    pub(super) reached_by_both: usize,
    pub(super) reach: [f64; 2],
    /// `x`'s success rate minus `y`'s, percentage points, and the half-width of its 95 %
    /// interval (Student's t over the per-leg differences).
    pub(super) difference: (f64, f64),
    /// How much sooner `x` reached the target than `y` on the legs both reached, seconds,
    /// and the half-width of its 95 % interval.
    pub(super) faster: (f64, f64),
}

impl Paired {
    pub(super) fn of(x: &Legs, y: &Legs, decision_dt: f64) -> Self {
        let pairs: Vec<(Option<u32>, Option<u32>)> = common_legs(&[x, y])
            .into_iter()
            .map(|l| (l[0], l[1]))
            .collect();
        let pct = |o: Option<u32>| if o.is_some() { 100.0 } else { 0.0 };
        let differences: Vec<f64> = pairs.iter().map(|&(a, b)| pct(a) - pct(b)).collect();
        let both: Vec<[f64; 2]> = pairs
            .iter()
            .filter_map(|&(a, b)| Some([f64::from(a?) * decision_dt, f64::from(b?) * decision_dt]))
            .collect();
        let sooner: Vec<f64> = both.iter().map(|[a, b]| b - a).collect();
        let mean = |xs: Vec<f64>| mean_ci(&xs).0;
        Self {
            legs: pairs.len(),
            success: [
                mean(pairs.iter().map(|p| pct(p.0)).collect()),
                mean(pairs.iter().map(|p| pct(p.1)).collect()),
            ],
            reached_by_both: both.len(),
            reach: [
                mean(both.iter().map(|b| b[0]).collect()),
                mean(both.iter().map(|b| b[1]).collect()),
            ],
            difference: mean_ci(&differences),
            faster: mean_ci(&sooner),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_confidence_interval_uses_students_t() {
        // sd 1, n 3: t(2) / sqrt(3).
        let (m, h) = mean_ci(&[1.0, 2.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((h - t975(2) / 3f64.sqrt()).abs() < 1e-12);
        assert!(mean_ci(&[5.0]).1.is_nan());
    }

    #[test]
    fn the_quantile_is_students_t() {
        // Textbook values, to the three decimals tables print.
        for (df, t) in [
            (1, 12.706),
            (2, 4.303),
            (10, 2.228),
            (30, 2.042),
            (1000, 1.962),
        ] {
            assert!((t975(df) - t).abs() < 5e-4, "df {df}: {}", t975(df));
        }
    }

    #[test]
    fn paired_legs_are_the_legs_both_models_drove() {
        // Part 0: env 0 drove 3 legs under x, 2 under y; env 1 one leg each. Part 1 only x.
        let x: Legs = vec![
            vec![vec![Some(10), None, Some(4)], vec![Some(6)]],
            vec![vec![None]],
        ];
        let y: Legs = vec![vec![vec![Some(12), Some(5)], vec![Some(8)]]];
        let c = Paired::of(&x, &y, 0.1);
        assert_eq!((c.legs, c.reached_by_both), (3, 2));
        assert_eq!(c.success, [200.0 / 3.0, 100.0]);
        // Reach times (1.0, 1.2) and (0.6, 0.8): x 0.2 s sooner on both legs, so ± 0.
        assert!((c.reach[0] - 0.8).abs() < 1e-12 && (c.reach[1] - 1.0).abs() < 1e-12);
        assert!((c.faster.0 - 0.2).abs() < 1e-12 && c.faster.1.abs() < 1e-12);
        // Differences {0, -100, 0} pp: mean -33.3, sd 57.7, t(2) = 4.303.
        let (d, half) = c.difference;
        assert!((d + 100.0 / 3.0).abs() < 1e-9);
        assert!((half - t975(2) * (10_000.0f64 / 3.0).sqrt() / 3f64.sqrt()).abs() < 1e-9);
    }
}
