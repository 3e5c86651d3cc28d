//! `[sim.task]`: the paper's episode and reward rules, and where episodes start.

use super::ConfigError;
use super::range::{count_in, in_range, invalid};
use serde::{Deserialize, Serialize};

/// The paper's episode and reward rules (SPEC S3–S4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct TaskConfig {
    /// Δ, metres (SPEC S3). (0, 1]. Default 0.1.
    pub delta: f64,
    /// Target annulus radii in units of Δ (SPEC S3: Δ ≤ r ≤ 5Δ). Default [1, 5].
    pub target_annulus: [f64; 2],
    /// MES = mes-base + mes-per-metre · ID (SPEC S3). Default 300, 200.
    pub mes_base: f64,
    pub mes_per_metre: f64,
    /// PED = ID + ped-slack·Δ − kΔ (SPEC S3). [0, 100]. Default 2.
    pub ped_slack: f64,
    /// Leaving the area by more than this ends the episode and respawns (SPEC S3, interpretation), metres. Default 0.2.
    pub leave_margin: f64,
    /// |roll| or |pitch| above this ends the episode and respawns (SPEC S3, interpretation), degrees. (0, 180]. Default 60.
    pub tip_limit_deg: f64,
    /// ProgressReward = progress-scale · PD (SPEC S4). Default 100.
    pub progress_scale: f64,
    /// Redraws before giving up on a target inside the area (then the last draw is clamped into the area). 1 ..= 10^6. Default 1000.
    pub max_target_draws: usize,
    /// Where episodes start: "chained" (SPEC S3) or "course" (paired evaluation). Default "chained".
    pub episodes: EpisodeStart,
    /// Not the paper's (SPEC S3 extension): a robot that has stayed within `stall-distance`
    /// of one spot for this many decision steps of an episode has stalled: the episode ends
    /// as a failure (terminal, like PED's) and the robot is respawned. Without it, a policy
    /// that stops on rough ground sees a truncation bootstrapped from the very state it sits
    /// in, so stopping costs it almost nothing and it may never learn to leave. 0 = off (the
    /// paper's rules). 0 ..= 100000. Default 0.
    pub stall_steps: u32,
    /// The stall rule's radius, metres: moving farther than this from where the robot stood
    /// restarts the count. (0, 10]. Default 0.02.
    pub stall_distance: f64,
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

impl TaskConfig {
    /// The longest an episode can last, decision steps: SPEC S3's MES at the farthest target
    /// the annulus allows (a target clamped into the area only comes closer).
    pub fn longest_episode_ticks(&self) -> u64 {
        (self.mes_base + self.mes_per_metre * self.target_annulus[1] * self.delta).floor() as u64
    }

    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        in_range("sim.task.delta", self.delta, 1e-3, 1.0)?;
        let [lo, hi] = self.target_annulus;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi && hi <= 50.0) {
            return Err(invalid(
                "sim.task.target-annulus",
                self.target_annulus,
                "needs 0 < min <= max <= 50",
            ));
        }
        in_range("sim.task.mes-base", self.mes_base, 1.0, 1e6)?;
        in_range("sim.task.mes-per-metre", self.mes_per_metre, 0.0, 1e6)?;
        in_range("sim.task.ped-slack", self.ped_slack, 0.0, 100.0)?;
        in_range("sim.task.leave-margin", self.leave_margin, 0.0, 100.0)?;
        in_range("sim.task.tip-limit-deg", self.tip_limit_deg, 1.0, 180.0)?;
        in_range("sim.task.progress-scale", self.progress_scale, 0.0, 1e6)?;
        count_in("sim.task.stall-steps", self.stall_steps, 0, 100_000)?;
        in_range("sim.task.stall-distance", self.stall_distance, 1e-6, 10.0)?;
        count_in(
            "sim.task.max-target-draws",
            self.max_target_draws,
            1,
            1_000_000,
        )?;
        Ok(())
    }
}

impl Default for TaskConfig {
    fn default() -> Self {
        Self {
            delta: 0.1,
            target_annulus: [1.0, 5.0],
            mes_base: 300.0,
            mes_per_metre: 200.0,
            ped_slack: 2.0,
            leave_margin: 0.2,
            tip_limit_deg: 60.0,
            progress_scale: 100.0,
            max_target_draws: 1000,
            episodes: EpisodeStart::Chained,
            stall_steps: 0,
            stall_distance: 0.02,
        }
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
