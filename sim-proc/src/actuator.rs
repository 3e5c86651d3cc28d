//! What stands between a wheel command and the wheels: the command's latency in physics
//! steps and the motors' first-order response (`sim.robot.command-latency`,
//! `sim.robot.motor-time-constant`). With neither, the wheels get each command at once, as in
//! the paper.

use common::config::RobotConfig;
use std::collections::VecDeque;

/// One robot's actuators between its commands and its wheels.
#[derive(Debug, Clone)]
pub struct Actuator {
    /// Commands sent and not yet received, oldest first: one per physics step of latency.
    in_flight: VecDeque<[f32; 2]>,
    /// The share of the way to the command the wheels' speed moves each physics step,
    /// 1 - exp(-dt/τ); `None` without a time constant.
    gain: Option<f32>,
    /// The speeds the wheels were last given, rad/s.
    speeds: [f32; 2],
}

impl Actuator {
    /// The actuators of `cfg` at a physics step of `dt` seconds, at rest.
    pub fn new(cfg: &RobotConfig, dt: f64) -> Self {
        let mut in_flight = VecDeque::with_capacity(cfg.command_latency + 1);
        in_flight.resize(cfg.command_latency, [0.0; 2]);
        Self {
            in_flight,
            gain: gain(cfg, dt),
            speeds: [0.0; 2],
        }
    }

    /// Whether the wheels get every command at once (the paper's).
    pub fn is_ideal(&self) -> bool {
        self.in_flight.is_empty() && self.gain.is_none()
    }

    /// The speeds the wheels drive at for one physics step while `command` is sent.
    pub fn apply(&mut self, command: [f32; 2]) -> [f32; 2] {
        self.in_flight.push_back(command);
        let arrived = self.in_flight.pop_front().unwrap_or(command);
        self.speeds = match self.gain {
            None => arrived,
            Some(k) => [0, 1].map(|i| self.speeds[i] + k * (arrived[i] - self.speeds[i])),
        };
        self.speeds
    }

    /// Takes `cfg`'s latency and time constant for the commands to come (a world drawn by
    /// `[sim.randomize]`), keeping the wheels' speeds: a longer delay line holds the speeds
    /// the wheels already drive at, a shorter one drops its oldest commands.
    pub fn retune(&mut self, cfg: &RobotConfig, dt: f64) {
        self.gain = gain(cfg, dt);
        while self.in_flight.len() > cfg.command_latency {
            self.in_flight.pop_front();
        }
        while self.in_flight.len() < cfg.command_latency {
            self.in_flight.push_front(self.speeds);
        }
    }

    /// At rest again, nothing in flight: a robot just placed.
    pub fn reset(&mut self) {
        self.in_flight.iter_mut().for_each(|c| *c = [0.0; 2]);
        self.speeds = [0.0; 2];
    }
}

/// The share of the way to the command the motors of `cfg` move each physics step of `dt`
/// seconds, 1 - exp(-dt/τ); `None` without a time constant.
fn gain(cfg: &RobotConfig, dt: f64) -> Option<f32> {
    (cfg.motor_time_constant > 0.0).then(|| (1.0 - (-dt / cfg.motor_time_constant).exp()) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retuning_keeps_the_commands_in_flight_it_still_has_room_for() {
        let mut a = Actuator::new(&robot(3, 0.0), 0.02);
        for c in [1.0, 2.0, 3.0] {
            a.apply([c, -c]);
        }
        a.retune(&robot(1, 0.0), 0.02);
        assert_eq!(
            a.apply([9.0, 9.0]),
            [3.0, -3.0],
            "the newest in flight arrives next"
        );
        a.retune(&robot(2, 0.0), 0.02);
        assert_eq!(
            a.apply([5.0, 5.0]),
            [3.0, -3.0],
            "the wheels hold their speed"
        );
        assert_eq!(a.apply([6.0, 6.0]), [9.0, 9.0]);
        a.retune(&robot(0, 0.0), 0.02);
        assert!(a.is_ideal());
    }

    fn robot(latency: usize, tau: f64) -> RobotConfig {
        RobotConfig {
            command_latency: latency,
            motor_time_constant: tau,
            ..RobotConfig::default()
        }
    }

    #[test]
    fn without_latency_or_lag_the_wheels_get_each_command_at_once() {
        let mut a = Actuator::new(&RobotConfig::default(), 0.02);
        assert!(a.is_ideal());
        assert_eq!(a.apply([1.5, -2.0]), [1.5, -2.0]);
        assert_eq!(a.apply([0.25, 3.0]), [0.25, 3.0]);
    }

    #[test]
    fn a_latency_of_k_steps_hands_on_each_command_k_steps_later() {
        let mut a = Actuator::new(&robot(3, 0.0), 0.02);
        assert!(!a.is_ideal());
        let got: Vec<f32> = (1..=6).map(|i| a.apply([i as f32, 0.0])[0]).collect();
        assert_eq!(got, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
        a.reset();
        assert_eq!(a.apply([9.0, 9.0]), [0.0, 0.0]);
    }

    #[test]
    fn a_time_constant_follows_one_minus_exp() {
        // τ = 0.1 s at dt = 0.02 s: gain 1 - e^-0.2 = 0.181269; after n steps of a unit step
        // command the speed is 1 - (1 - gain)^n = 1 - e^(-0.2 n): 0.632121 after 5 (one τ).
        let mut a = Actuator::new(&robot(0, 0.1), 0.02);
        let first = a.apply([1.0, -1.0]);
        assert!((first[0] - 0.181_269).abs() < 1e-6, "{first:?}");
        assert_eq!(first[1], -first[0]);
        let fifth = (0..4)
            .map(|_| a.apply([1.0, -1.0]))
            .last()
            .expect("four steps");
        assert!((fifth[0] - 0.632_121).abs() < 1e-5, "{fifth:?}");
    }
}
