//! Rolling standard deviation of one series over its last `w` values, O(1) per value.
//!
//! Numerics: the window's mean and sum of squared deviations (M2) are updated in place
//! (Welford's add while filling, then a combined add-and-remove per value). That update is
//! stable for one step, but its rounding errors accumulate with the number of updates, and a
//! burst of large values can leave a residue in M2 after it has left the window. So every time
//! the ring buffer wraps (every `w` values) the mean and M2 are recomputed exactly, two-pass,
//! from the buffer: the state never carries more than `w` updates of drift, whatever the series
//! length, and the recomputation costs O(w) every `w` values, i.e. O(1) amortised.

/// Which divisor the variance uses.
///
/// The paper's analysis is Python: pandas' `Series.rolling(w).std()` is the **sample** std
/// (`ddof = 1`, divide by `w − 1`), which is the default here. `Population` divides by `w`
/// (numpy's `np.std` default).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Ddof {
    #[default]
    Sample,
    Population,
}

impl Ddof {
    fn divisor(self, n: usize) -> f64 {
        match self {
            Ddof::Sample => (n - 1) as f64,
            Ddof::Population => n as f64,
        }
    }
}

/// The std of the last `window` values pushed; defined only once the window is full (as
/// pandas' default `min_periods = window`).
#[derive(Debug, Clone)]
pub struct RollingStd {
    buf: Vec<f64>,
    head: usize,
    len: usize,
    mean: f64,
    m2: f64,
    ddof: Ddof,
}

impl RollingStd {
    /// A window of `window` values; `window` must be at least 2 (a 1-value sample std is undefined).
    pub fn new(window: usize, ddof: Ddof) -> crate::Result<Self> {
        if window < 2 {
            return Err(crate::EstimatorError::BadWindow { window });
        }
        Ok(Self {
            buf: vec![0.0; window],
            head: 0,
            len: 0,
            mean: 0.0,
            m2: 0.0,
            ddof,
        })
    }

    pub fn window(&self) -> usize {
        self.buf.len()
    }

    /// Values currently in the window (reaches `window` and stays there).
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Forgets every value (e.g. after a respawn).
    pub fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
        self.mean = 0.0;
        self.m2 = 0.0;
    }

    /// Adds `x` (the caller guarantees it is finite) and returns the std of the window if full.
    pub fn push(&mut self, x: f64) -> Option<f64> {
        let w = self.buf.len();
        if self.len < w {
            self.len += 1;
            let delta = x - self.mean;
            self.mean += delta / self.len as f64;
            self.m2 += delta * (x - self.mean);
        } else {
            let old = self.buf[self.head];
            let old_mean = self.mean;
            self.mean += (x - old) / w as f64;
            self.m2 += (x - old) * (x - self.mean + old - old_mean);
        }
        self.buf[self.head] = x;
        self.head += 1;
        if self.head == w {
            self.head = 0;
            self.recompute();
        }
        self.std()
    }

    /// The std of the full window, or `None` while it fills.
    pub fn std(&self) -> Option<f64> {
        (self.len == self.buf.len())
            .then(|| (self.m2.max(0.0) / self.ddof.divisor(self.len)).sqrt())
    }

    /// Exact two-pass mean and M2 of the buffered values.
    fn recompute(&mut self) {
        let values = &self.buf[..self.len];
        let n = values.len() as f64;
        self.mean = values.iter().sum::<f64>() / n;
        self.m2 = values
            .iter()
            .map(|v| (v - self.mean) * (v - self.mean))
            .sum();
    }
}

/// The ground distance a robot covered over its last `window` positions: the sum of the
/// `window − 1` steps between them, O(1) per position; the same windows as [`RollingStd`],
/// so the two can gate each other (`estimator.min-speed`).
#[derive(Debug, Clone)]
pub struct RollingPath {
    steps: Vec<f64>,
    head: usize,
    len: usize,
    sum: f64,
    last: Option<[f64; 2]>,
    /// The next position follows a jump ([`RollingPath::jump`]).
    jumped: bool,
}

impl RollingPath {
    /// A window of `window` positions, at least 2.
    pub fn new(window: usize) -> crate::Result<Self> {
        if window < 2 {
            return Err(crate::EstimatorError::BadWindow { window });
        }
        Ok(Self {
            steps: vec![0.0; window - 1],
            head: 0,
            len: 0,
            sum: 0.0,
            last: None,
            jumped: false,
        })
    }

    /// Adds a position (X-Z, metres) and returns the path length over the window once full.
    pub fn push(&mut self, p: [f64; 2]) -> Option<f64> {
        if let Some(q) = self.last.replace(p) {
            let step = if std::mem::take(&mut self.jumped) {
                0.0
            } else {
                (p[0] - q[0]).hypot(p[1] - q[1])
            };
            let n = self.steps.len();
            if self.len == n {
                self.sum -= self.steps[self.head];
            } else {
                self.len += 1;
            }
            self.steps[self.head] = step;
            self.sum += step;
            self.head = (self.head + 1) % n;
            if self.head == 0 {
                // Exact again once per lap, as `RollingStd`: no drift from the subtractions.
                self.sum = self.steps[..self.len].iter().sum();
            }
        }
        (self.len == self.steps.len()).then_some(self.sum.max(0.0))
    }

    /// Forgets every position.
    pub fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
        self.sum = 0.0;
        self.last = None;
        self.jumped = false;
    }

    /// The robot was put somewhere else: the next position adds a step of no length, so the
    /// window's path is the path driven.
    pub fn jump(&mut self) {
        self.jumped = true;
    }
}

/// Path lengths of `xz` over every full window, aligned with [`rolling_std`]'s values.
pub fn rolling_path(xz: &[[f64; 2]], window: usize) -> crate::Result<Vec<f64>> {
    let mut r = RollingPath::new(window)?;
    Ok(xz.iter().filter_map(|&p| r.push(p)).collect())
}

/// The rolling std of `xs` at every index where a full window ends: `xs.len() − w + 1`
/// values (none if the series is shorter than `w`), as pandas' `rolling(w).std().dropna()`.
pub fn rolling_std(xs: &[f64], window: usize, ddof: Ddof) -> crate::Result<Vec<f64>> {
    let mut r = RollingStd::new(window, ddof)?;
    Ok(xs.iter().filter_map(|&x| r.push(x)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rolling_path_sums_the_steps_inside_the_window() {
        // A 3-4-5 step, a 1 m step, a standstill, a 2 m step; window 3 = the last 2 steps.
        let xz = [[0.0, 0.0], [3.0, 4.0], [4.0, 4.0], [4.0, 4.0], [4.0, 6.0]];
        assert_eq!(rolling_path(&xz, 3).expect("window"), vec![6.0, 1.0, 2.0]);
        let mut r = RollingPath::new(2).expect("window");
        assert_eq!(r.push([0.0, 0.0]), None, "one position is no step");
        assert_eq!(r.push([0.0, 0.5]), Some(0.5));
        r.clear();
        assert_eq!(
            r.push([9.0, 9.0]),
            None,
            "cleared: no step from the old position"
        );
        assert!(RollingPath::new(1).is_err());
        // A jump adds a step of no length: 1 m, the jump, 1 m over window 4.
        let mut r = RollingPath::new(4).expect("window");
        r.push([0.0, 0.0]);
        r.push([1.0, 0.0]);
        r.jump();
        r.push([5.0, 0.0]);
        assert_eq!(r.push([6.0, 0.0]), Some(2.0));
        // Many laps: the running sum stays exact.
        let walk: Vec<[f64; 2]> = (0..10_000).map(|i| [0.1 * f64::from(i), 0.0]).collect();
        let last = *rolling_path(&walk, 70)
            .expect("window")
            .last()
            .expect("full");
        assert!((last - 6.9).abs() < 1e-9, "{last}");
    }

    fn naive(xs: &[f64], ddof: Ddof) -> f64 {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let ss: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
        (ss / ddof.divisor(xs.len())).sqrt()
    }

    #[test]
    fn hand_computed_sample_and_population() {
        // Window [1, 2, 3, 4]: mean 2.5, squared deviations sum to 5.
        let s = rolling_std(&[1.0, 2.0, 3.0, 4.0], 4, Ddof::Sample).expect("window");
        assert_eq!(s.len(), 1);
        assert!((s[0] - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        let p = rolling_std(&[1.0, 2.0, 3.0, 4.0], 4, Ddof::Population).expect("window");
        assert!((p[0] - (5.0f64 / 4.0).sqrt()).abs() < 1e-15);
        // Sliding by one: [2, 3, 4, 10]: mean 4.75, deviations² sum 38.75.
        let s = rolling_std(&[1.0, 2.0, 3.0, 4.0, 10.0], 4, Ddof::Sample).expect("window");
        assert!((s[1] - (38.75f64 / 3.0).sqrt()).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn undefined_until_full_and_short_series_give_nothing() {
        let mut r = RollingStd::new(3, Ddof::Sample).expect("window");
        assert_eq!(r.push(1.0), None);
        assert_eq!(r.push(2.0), None);
        assert!(r.push(3.0).is_some());
        assert!(
            rolling_std(&[1.0, 2.0], 3, Ddof::Sample)
                .expect("window")
                .is_empty()
        );
        assert!(matches!(
            RollingStd::new(1, Ddof::Sample),
            Err(crate::EstimatorError::BadWindow { window: 1 })
        ));
    }

    #[test]
    fn constant_window_is_exactly_zero_after_a_spike() {
        // A huge value passes through the window; once it has left, the std of a constant
        // window must be 0 (not the residue of cancelling 1e8² against itself).
        let mut xs = vec![0.5; 10];
        xs.push(1e8);
        xs.extend(std::iter::repeat_n(0.5, 30));
        let s = rolling_std(&xs, 10, Ddof::Sample).expect("window");
        assert!(s.last().is_some_and(|&v| v == 0.0), "{:?}", s.last());
    }

    #[test]
    fn stays_accurate_over_millions_of_values() {
        // Pitch-like data with an offset: after 3 M updates the last window still matches a
        // fresh two-pass computation to ~1e-12 relative.
        let mut rng = common::Rng::new(11);
        let w = 70;
        let mut r = RollingStd::new(w, Ddof::Sample).expect("window");
        let mut tail = std::collections::VecDeque::new();
        let mut last = None;
        for _ in 0..3_000_000 {
            let x = 0.3 + 0.05 * rng.normal();
            tail.push_back(x);
            if tail.len() > w {
                tail.pop_front();
            }
            last = r.push(x);
        }
        let tail: Vec<f64> = tail.into();
        let exact = naive(&tail, Ddof::Sample);
        let got = last.expect("full window");
        assert!(((got - exact) / exact).abs() < 1e-12, "{got} vs {exact}");
    }

    proptest! {
        #[test]
        fn equals_naive_recomputation(
            xs in prop::collection::vec(-1.0f64..1.0, 2..400),
            w in 2usize..60,
            population in any::<bool>(),
        ) {
            let ddof = if population { Ddof::Population } else { Ddof::Sample };
            let got = rolling_std(&xs, w, ddof).expect("window");
            prop_assert_eq!(got.len(), xs.len().saturating_sub(w - 1));
            for (i, g) in got.iter().enumerate() {
                let window = &xs[i..i + w];
                let exact = naive(window, ddof);
                // A std far below the values' own size (two values 7e-6 apart near 0.93) is
                // a difference of nearly equal sums: the variance is then only good to the
                // rounding of the values' squares.
                let scale = window.iter().map(|x| x * x).fold(0.0, f64::max);
                prop_assert!(
                    (g - exact).abs() <= 1e-12 + 1e-9 * exact
                        || (g * g - exact * exact).abs() <= 64.0 * f64::EPSILON * scale,
                    "i={} {} vs {}", i, g, exact
                );
            }
        }
    }
}
