//! `[sim.randomize]`: domain randomization, beyond the paper. Each episode of each env draws
//! its own world from these ranges, from a stream of its own, so the policy trains (or is
//! evaluated) across robots and grounds rather than on one. Every field at its default draws
//! nothing: the paper's one world, bit for bit.

use super::ConfigError;
use super::range::invalid;
use super::setting::{count, real, settings};

settings! {
    /// Per-episode draws of the world (beyond the paper); a `[lo, hi]` range is drawn uniformly.
    pub struct RandomizeConfig {
        /// Each terrain kind's ground friction times its own draw from this range.
        pub friction_scale: [f64; 2] = [1.0, 1.0] => real(0.05, 10.0), "×", Research;
        /// The chassis mass times a draw from this range.
        pub mass_scale: [f64; 2] = [1.0, 1.0] => real(0.1, 10.0), "×", Research;
        /// The chassis's centre of mass moves along each of its axes (x across, y up, z along)
        /// by a draw within ± this.
        pub com_offset: [f64; 3] = [0.0; 3] => real(0.0, 0.5), "m", Research;
        /// A payload: a point mass drawn from this range, on top of the chassis's centre.
        pub payload: [f64; 2] = [0.0, 0.0] => real(0.0, 100.0), "kg", Research;
        /// Both wheels' radius times a draw from this range.
        pub wheel_radius_scale: [f64; 2] = [1.0, 1.0] => real(0.5, 2.0), "×", Research;
        /// The wheel motors' torque limit times a draw from this range.
        pub torque_scale: [f64; 2] = [1.0, 1.0] => real(0.01, 100.0), "×", Research;
        /// The wheel motors' velocity gain (`robot.motor-damping`) times a draw from this range.
        pub gain_scale: [f64; 2] = [1.0, 1.0] => real(0.001, 1000.0), "×", Research;
        /// Physics steps of latency added to `robot.command-latency`, a whole number drawn from
        /// this range (ends included).
        pub latency: [usize; 2] = [0, 0] => count(0, 100), "physics steps", Research;
        /// Seconds added to `robot.motor-time-constant`, drawn from this range.
        pub time_constant: [f64; 2] = [0.0, 0.0] => real(0.0, 10.0), "s", Research;
        /// `sim.gravity` times a draw from this range.
        pub gravity_scale: [f64; 2] = [1.0, 1.0] => real(0.01, 5.0), "×", Research;
        /// Every IMU error term (noise densities, bias walks, turn-on biases, scale errors) times
        /// a draw from this range; the sensors' biases and scale errors are drawn again.
        pub imu_error_scale: [f64; 2] = [1.0, 1.0] => real(0.0, 100.0), "×", Research;
        /// σ of Gaussian noise on each of the target's three robot-frame coordinates in the
        /// observation, drawn every tick (the norm term is that of the noisy target).
        pub target_noise: f64 = 0.0 => real(0.0, 10.0), "m", Research;
        /// σ of Gaussian noise on each observed attitude angle (θx, θy, θz) before its cos and
        /// sin, drawn every tick.
        pub attitude_noise: f64 = 0.0 => real(0.0, 1.0), "rad", Research;
        /// Size of each push: a horizontal impulse on the chassis in a random direction.
        pub push_impulse: [f64; 2] = [0.0, 0.0] => real(0.0, 100.0), "N·s", Research;
        /// Seconds of an episode between pushes; 0 never pushes.
        pub push_interval: f64 = 0.0 => real(0.0, 3600.0), "s", Research;
    }
}

impl RandomizeConfig {
    /// Whether any episode's world differs from the nominal one: some range is not the
    /// identity, some noise is on, or pushes come.
    pub fn is_active(&self) -> bool {
        *self != Self::default()
    }

    /// Whether the robots are pushed.
    pub fn pushes(&self) -> bool {
        self.push_interval > 0.0 && self.push_impulse[1] > 0.0
    }

    /// Every range's ends in order.
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        let reals = [
            ("friction-scale", self.friction_scale),
            ("mass-scale", self.mass_scale),
            ("payload", self.payload),
            ("wheel-radius-scale", self.wheel_radius_scale),
            ("torque-scale", self.torque_scale),
            ("gain-scale", self.gain_scale),
            ("time-constant", self.time_constant),
            ("gravity-scale", self.gravity_scale),
            ("imu-error-scale", self.imu_error_scale),
            ("push-impulse", self.push_impulse),
        ];
        let latency = self.latency.map(|n| n as f64);
        for (name, [lo, hi]) in reals.into_iter().chain([("latency", latency)]) {
            if lo > hi {
                return Err(invalid(
                    &format!("sim.randomize.{name}"),
                    [lo, hi],
                    "is a [lo, hi] range: lo must not exceed hi",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_draws_nothing_and_any_range_turns_it_on() {
        assert!(!RandomizeConfig::default().is_active());
        let heavier = RandomizeConfig {
            mass_scale: [1.0, 2.0],
            ..RandomizeConfig::default()
        };
        assert!(heavier.is_active());
        let noisy = RandomizeConfig {
            attitude_noise: 0.01,
            ..RandomizeConfig::default()
        };
        assert!(noisy.is_active() && !noisy.pushes());
    }

    #[test]
    fn a_range_whose_ends_are_swapped_is_refused_by_name() {
        let swapped = RandomizeConfig {
            latency: [3, 1],
            ..RandomizeConfig::default()
        };
        let err = swapped.validate().expect_err("swapped").to_string();
        assert!(err.contains("sim.randomize.latency"), "{err}");
        assert!(err.contains("lo must not exceed hi"), "{err}");
    }
}
