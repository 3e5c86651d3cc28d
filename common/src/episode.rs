//! Episode outcomes, counted by the process that ends the episodes and carried as they are
//! (the sim puts them in every [`TickHeader`]), so every reader derives the success rate
//! and the reach time (SPEC S8's Table 1) from the same sums with the same formulas.

use crate::wire::TickHeader;

/// Finished episodes: how many, how many reached their target, and the sums of the
/// successful ones' lengths in decision ticks and of their squares. Integer sums are exact
/// and merge by addition, so the moments need no list of episodes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EpisodeStats {
    pub episodes: u64,
    pub successes: u64,
    pub reach_ticks: u64,
    pub reach_ticks_sq: u64,
}

impl EpisodeStats {
    /// Counts one finished episode that lasted `ticks` decision ticks; only a success adds
    /// its length to the reach-time sums.
    pub fn record(&mut self, success: bool, ticks: u64) {
        self.episodes += 1;
        if success {
            self.successes += 1;
            self.reach_ticks += ticks;
            self.reach_ticks_sq += ticks * ticks;
        }
    }

    /// Adds `other`'s episodes to these (e.g. several sims' or several chunks' counts).
    pub fn merge(&mut self, other: &Self) {
        self.episodes += other.episodes;
        self.successes += other.successes;
        self.reach_ticks += other.reach_ticks;
        self.reach_ticks_sq += other.reach_ticks_sq;
    }

    /// Successes over episodes; 0 before any episode ended.
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.episodes.max(1) as f64
    }

    /// Mean and (population) std of the successful episodes' reach time, seconds, with
    /// `decision_dt` seconds per tick; `None` before any success.
    pub fn reach_seconds(&self, decision_dt: f64) -> Option<(f64, f64)> {
        let n = self.successes as f64;
        (n > 0.0).then(|| {
            let mean = self.reach_ticks as f64 / n;
            // E[t²] − E[t]² can dip below zero by rounding when every length is the same.
            let var = (self.reach_ticks_sq as f64 / n - mean * mean).max(0.0);
            (mean * decision_dt, var.sqrt() * decision_dt)
        })
    }
}

impl From<&TickHeader> for EpisodeStats {
    /// The counts the sim carried in a telemetry tick.
    fn from(h: &TickHeader) -> Self {
        Self {
            episodes: h.episodes,
            successes: h.successes,
            reach_ticks: h.reach_ticks,
            reach_ticks_sq: h.reach_ticks_sq,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Successes of 10 and 20 ticks and one failure of 7.
    fn three() -> EpisodeStats {
        let mut s = EpisodeStats::default();
        s.record(true, 10);
        s.record(false, 7);
        s.record(true, 20);
        s
    }

    #[test]
    fn record_counts_episodes_and_sums_only_successes() {
        let s = three();
        assert_eq!(
            (s.episodes, s.successes, s.reach_ticks, s.reach_ticks_sq),
            (3, 2, 30, 100 + 400)
        );
    }

    #[test]
    fn success_rate_and_reach_time_match_hand_values() {
        let s = three();
        assert_eq!(s.success_rate(), 2.0 / 3.0);
        // Mean 15 ticks, E[t²] = 250, var = 250 − 225 = 25: at 0.1 s per tick, 1.5 s ± 0.5 s.
        assert_eq!(s.reach_seconds(0.1), Some((1.5, 0.5)));
        // One tick per second gives the moments in ticks.
        assert_eq!(s.reach_seconds(1.0), Some((15.0, 5.0)));
    }

    #[test]
    fn nothing_finished_gives_zero_rate_and_no_reach_time() {
        let none = EpisodeStats::default();
        assert_eq!(none.success_rate(), 0.0);
        assert_eq!(none.reach_seconds(0.1), None);
        let mut failed = EpisodeStats::default();
        failed.record(false, 40);
        assert_eq!(
            (failed.success_rate(), failed.reach_seconds(0.1)),
            (0.0, None)
        );
    }

    #[test]
    fn equal_lengths_have_zero_std() {
        let mut s = EpisodeStats::default();
        for _ in 0..3 {
            s.record(true, 7);
        }
        assert_eq!(s.reach_seconds(1.0), Some((7.0, 0.0)));
    }

    #[test]
    fn merging_equals_recording_everything_in_one() {
        let mut a = EpisodeStats::default();
        a.record(true, 10);
        let mut b = EpisodeStats::default();
        b.record(false, 7);
        b.record(true, 20);
        a.merge(&b);
        assert_eq!(a, three());
    }

    #[test]
    fn a_tick_header_carries_the_counts() {
        let h = TickHeader {
            episodes: 3,
            successes: 2,
            reach_ticks: 30,
            reach_ticks_sq: 500,
            ..TickHeader::default()
        };
        assert_eq!(EpisodeStats::from(&h), three());
    }
}
