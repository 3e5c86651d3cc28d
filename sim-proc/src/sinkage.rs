//! Loose sand (`sim.terrain.sand`): a wheel that spins fast digs itself in.
//!
//! Not a terramechanics solver, but the behaviour of loose granular ground that matters to a
//! driving policy: a wheel turning faster than the sand under it can carry throws the sand
//! out and sinks (slip-sinkage), and a sunk wheel spins in its rut without pushing. Each wheel
//! carries a sinkage s ∈ [0, 1]. On sand, while its rim speed |ω|·r is above `dig-speed`, s
//! grows by `dig-rate` per metre of rim travel above that speed; otherwise, and off sand, it
//! decays with time constant `settle-time` as the wheel rolls out. The wheel's friction slides
//! from `robot.wheel-friction` at s = 0 to `dug-friction` at s = 1, and the contact solver
//! does the rest: a dug-in robot spins its wheels where it stands.

use crate::robot::Robot;
use common::config::{RobotConfig, SandConfig};
use rapier3d::prelude::PhysicsWorld;

/// Below this a sinkage counts as none (an exponential decay never reaches 0).
const SETTLED: f64 = 1e-4;

/// One wheel's sinkage after `dt` seconds at rim speed `rim` (m/s), on sand or not.
pub fn advance(cfg: &SandConfig, sinkage: f64, rim: f64, on_sand: bool, dt: f64) -> f64 {
    let s = if on_sand && rim > cfg.dig_speed {
        sinkage + cfg.dig_rate * (rim - cfg.dig_speed) * dt
    } else {
        sinkage * (-dt / cfg.settle_time).exp()
    };
    if s < SETTLED { 0.0 } else { s.min(1.0) }
}

/// A wheel's friction at `sinkage`: from `free` (the robot's wheel friction) to `dug-friction`.
pub fn friction(cfg: &SandConfig, free: f64, sinkage: f64) -> f64 {
    free + (cfg.dug_friction - free) * sinkage
}

/// Both wheels' sinkage in one env's world.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sinkage {
    /// Left, right, as [`Robot`]'s wheels.
    pub depth: [f64; 2],
}

impl Sinkage {
    /// Advances both wheels over a decision step of `dt` seconds at wheel commands `command`
    /// (rad/s), `on_sand` telling which stand on sand, and sets their friction in `world`.
    pub fn step(
        &mut self,
        sand: &SandConfig,
        robot_cfg: &RobotConfig,
        (world, robot): (&mut PhysicsWorld, &Robot),
        command: [f32; 2],
        on_sand: [bool; 2],
        dt: f64,
    ) {
        let before = self.depth;
        for side in 0..2 {
            let rim = f64::from(command[side]).abs() * robot_cfg.wheel_radius;
            self.depth[side] = advance(sand, self.depth[side], rim, on_sand[side], dt);
        }
        if self.depth != before {
            let mu = self
                .depth
                .map(|s| friction(sand, robot_cfg.wheel_friction, s) as f32);
            robot.set_wheel_friction(world, mu);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wheel_digs_above_the_dig_speed_and_rolls_out_below_it() {
        let cfg = SandConfig::default();
        // 3 rad/s × 0.035 m = 0.105 m/s, 0.045 above 0.06: 20 × 0.045 × 0.1 = 0.09 a step.
        let s = advance(&cfg, 0.0, 0.105, true, 0.1);
        assert!((s - 0.09).abs() < 1e-12, "{s}");
        // Full after 1 / 0.9 s, and never past 1.
        assert_eq!(advance(&cfg, 0.95, 0.105, true, 0.1), 1.0);
        // At the dig speed, or off sand, it decays: e^(−0.1 / 1 s) a step.
        let decayed = advance(&cfg, 0.5, 0.06, true, 0.1);
        assert!((decayed - 0.5 * (-0.1f64).exp()).abs() < 1e-12);
        assert_eq!(advance(&cfg, 0.5, 0.105, false, 0.1), decayed);
        assert_eq!(advance(&cfg, 1e-4, 0.0, true, 0.1), 0.0, "settled");
        // Friction: 1.0 free, 0.05 dug, halfway at half sinkage.
        assert_eq!(friction(&cfg, 1.0, 0.0), 1.0);
        assert!((friction(&cfg, 1.0, 1.0) - 0.05).abs() < 1e-12);
        assert!((friction(&cfg, 1.0, 0.5) - 0.525).abs() < 1e-12);
    }
}
