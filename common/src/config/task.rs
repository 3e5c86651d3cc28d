//! `[sim.task]`: the paper's episode and reward rules, and where episodes start.

use super::ConfigError;
use super::range::invalid;
use super::setting::{Setting, choices, count, real, settings};
use serde::{Deserialize, Serialize};

settings! {
    /// The paper's episode and reward rules (SPEC S3–S4).
    pub struct TaskConfig {
        /// Δ (SPEC S3), the length the target annulus and PED's slack are counted in.
        pub delta: f64 = 0.1 => real(1e-3, 1.0), "m", Research;
        /// Target annulus radii [min, max] in units of Δ (SPEC S3: Δ ≤ r ≤ 5Δ); 0 < min ≤ max.
        pub target_annulus: [f64; 2] = [1.0, 5.0] => real(0.0, 50.0), "Δ", Research;
        /// MES = mes-base + mes-per-metre · ID (SPEC S3): the constant term.
        pub mes_base: f64 = 300.0 => real(1.0, 1e6), "steps", Research;
        /// MES = mes-base + mes-per-metre · ID (SPEC S3): the steps per metre of ID.
        pub mes_per_metre: f64 = 200.0 => real(0.0, 1e6), "steps/m", Research;
        /// PED = ID + ped-slack·Δ − kΔ (SPEC S3).
        pub ped_slack: f64 = 2.0 => real(0.0, 100.0), "Δ", Research;
        /// Leaving the area by more than this ends the episode and respawns (SPEC S3,
        /// interpretation).
        pub leave_margin: f64 = 0.2 => real(0.0, 100.0), "m", Research;
        /// |roll| or |pitch| above this ends the episode and respawns (SPEC S3, interpretation).
        pub tip_limit_deg: f64 = 60.0 => real(1.0, 180.0), "deg", Research;
        /// ProgressReward = progress-scale · PD (SPEC S4).
        pub progress_scale: f64 = 100.0 => real(0.0, 1e6), "1/m", Research;
        /// Redraws before giving up on a target inside the area (then the last draw is clamped
        /// into the area).
        pub max_target_draws: usize = 1000 => count(1, 1_000_000), "draws", Advanced;
        /// Where episodes start: `chained` (SPEC S3) or `course` (paired evaluation).
        pub episodes: EpisodeStart = EpisodeStart::Chained
            => choices::<EpisodeStart>(), "", Research;
        /// Not the paper's (SPEC S3 extension): a robot that has stayed within `stall-distance`
        /// of one spot for this many decision steps of an episode has stalled: the episode ends
        /// as a failure (terminal, like PED's) and the robot is respawned. Without it, a policy
        /// that stops on rough ground sees a truncation bootstrapped from the very state it sits
        /// in, so stopping costs it almost nothing and it may never learn to leave. 0 = off (the
        /// paper's rules).
        pub stall_steps: u32 = 0 => count(0, 100_000), "steps", Research;
        /// The stall rule's radius: moving farther than this from where the robot stood
        /// restarts the count.
        pub stall_distance: f64 = 0.02 => real(1e-6, 10.0), "m", Research;
    }
}

/// Where an env's next episode starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EpisodeStart {
    /// SPEC S3: where the robot stands, with a new target drawn around it.
    Chained,
    /// A course of seeded waypoints, the same for every policy: leg k starts with the robot
    /// placed at waypoint k (the last leg's target, whatever happened on that leg) facing a
    /// seeded heading, and drives to waypoint k + 1, drawn around it by SPEC S3's rule. Two
    /// policies on one seed drive the same legs, so their outcomes pair leg by leg.
    Course,
}

impl Setting for EpisodeStart {}

impl TaskConfig {
    /// The longest an episode can last, decision steps: SPEC S3's MES at the farthest target
    /// the annulus allows (a target clamped into the area only comes closer).
    pub fn longest_episode_ticks(&self) -> u64 {
        (self.mes_base + self.mes_per_metre * self.target_annulus[1] * self.delta).floor() as u64
    }

    /// The rules between fields (each field's own range is [`super::setting::Setting::check`]'s).
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        let [lo, hi] = self.target_annulus;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi && hi <= 50.0) {
            return Err(invalid(
                "sim.task.target-annulus",
                self.target_annulus,
                "needs 0 < min <= max <= 50",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_episode_is_the_farthest_targets_limit() {
        // SPEC S3: MES = 300 + 200 · ID, ID at most 5Δ = 0.5 m.
        assert_eq!(TaskConfig::default().longest_episode_ticks(), 400);
    }
}
