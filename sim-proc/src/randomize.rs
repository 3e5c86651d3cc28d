//! Domain randomization (`[sim.randomize]`, beyond the paper): the world each episode of an
//! env draws, and the noise on its observations.
//!
//! Episode k of env i draws its world from stream k of env i's own seed, so a draw depends on
//! the run seed, the env and the episode's index alone: not on the thread count, not on what
//! the policy did (an evaluation course gives every policy the same worlds leg by leg), and
//! one env's draws never shift another's. The same holds for the observation noise of tick t.

use common::Rng;
use common::config::{AreaKind, ImuConfig, SensorErrors, SimConfig};

/// Env `id`'s worlds come from stream `WORLD_STREAMS + id` of the run seed.
const WORLD_STREAMS: u64 = 3 << 32;
/// Env `id`'s observation noise comes from stream `NOISE_STREAMS + id` of the run seed.
const NOISE_STREAMS: u64 = 4 << 32;

/// One episode's world: every value drawn, as the robot and its world take it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldDraw {
    /// Each terrain kind's ground friction factor, in [`AreaKind::KINDS`]' order.
    pub friction_scale: [f64; AreaKind::KINDS.len()],
    /// Chassis mass, kg.
    pub chassis_mass: f64,
    /// The chassis's centre of mass moved by this (x across, y up, z along), m.
    pub com_offset: [f64; 3],
    /// The payload's mass, kg.
    pub payload: f64,
    /// Wheel radius, m.
    pub wheel_radius: f64,
    /// The motors' torque limit, N·m.
    pub motor_max_torque: f64,
    /// The motors' velocity gain.
    pub motor_damping: f64,
    /// Command latency, physics steps.
    pub command_latency: usize,
    /// Motor time constant, s.
    pub motor_time_constant: f64,
    /// Gravity's magnitude, m/s².
    pub gravity: f64,
    /// The factor on every IMU error term.
    pub imu_error_scale: f64,
}

impl WorldDraw {
    /// The CSV header of [`WorldDraw::values`], after `env,episode`.
    pub fn columns() -> Vec<String> {
        let kinds = AreaKind::KINDS.map(|k| format!("friction_scale_{}", k.name()));
        let rest = [
            "chassis_mass",
            "com_x",
            "com_y",
            "com_z",
            "payload",
            "wheel_radius",
            "motor_max_torque",
            "motor_damping",
            "command_latency",
            "motor_time_constant",
            "gravity",
            "imu_error_scale",
        ];
        kinds.into_iter().chain(rest.map(String::from)).collect()
    }

    /// Every value, in [`WorldDraw::columns`]' order.
    pub fn values(&self) -> Vec<f64> {
        let c = self.com_offset;
        let rest = [
            self.chassis_mass,
            c[0],
            c[1],
            c[2],
            self.payload,
            self.wheel_radius,
            self.motor_max_torque,
            self.motor_damping,
            self.command_latency as f64,
            self.motor_time_constant,
            self.gravity,
            self.imu_error_scale,
        ];
        self.friction_scale.into_iter().chain(rest).collect()
    }

    /// The ground friction factor of `kind` (1 on the mixed course's own label, which no
    /// ground has).
    pub fn friction_of(&self, kind: AreaKind) -> f64 {
        AreaKind::KINDS
            .iter()
            .position(|k| *k == kind)
            .map_or(1.0, |i| self.friction_scale[i])
    }

    /// Writes this world's robot, gravity and IMU into `cfg`, an env's copy of `nominal` (the
    /// IMU's errors are `nominal`'s scaled).
    pub fn configure(&self, cfg: &mut SimConfig, nominal: &SimConfig) {
        let r = &mut cfg.robot;
        r.chassis_mass = self.chassis_mass;
        r.wheel_radius = self.wheel_radius;
        r.motor_max_torque = self.motor_max_torque;
        r.motor_damping = self.motor_damping;
        r.command_latency = self.command_latency;
        r.motor_time_constant = self.motor_time_constant;
        cfg.gravity = self.gravity;
        cfg.imu = scaled_imu(&nominal.imu, self.imu_error_scale);
    }

    /// The world `cfg` describes, nothing drawn.
    pub fn nominal(cfg: &SimConfig) -> Self {
        let r = &cfg.robot;
        Self {
            friction_scale: [1.0; AreaKind::KINDS.len()],
            chassis_mass: r.chassis_mass,
            com_offset: [0.0; 3],
            payload: 0.0,
            wheel_radius: r.wheel_radius,
            motor_max_torque: r.motor_max_torque,
            motor_damping: r.motor_damping,
            command_latency: r.command_latency,
            motor_time_constant: r.motor_time_constant,
            gravity: cfg.gravity,
            imu_error_scale: 1.0,
        }
    }
}

/// `imu` with every error term times `s`.
fn scaled_imu(imu: &ImuConfig, s: f64) -> ImuConfig {
    fn scaled<S: Clone>(e: &SensorErrors<S>, s: f64) -> SensorErrors<S> {
        SensorErrors {
            noise_density: e.noise_density * s,
            bias_walk: e.bias_walk * s,
            turn_on_bias: e.turn_on_bias * s,
            scale_error: e.scale_error * s,
            ..e.clone()
        }
    }
    ImuConfig {
        gyro: scaled(&imu.gyro, s),
        accel: scaled(&imu.accel, s),
        ..imu.clone()
    }
}

/// One env's randomization: its nominal world, its streams and its current episode's draw.
#[derive(Debug, Clone)]
pub struct Randomizer {
    /// The env's config as written, `[sim.randomize]` with it.
    nominal: SimConfig,
    /// Seeds episode k's world as stream k.
    worlds: u64,
    /// Seeds tick t's observation noise as stream t.
    noise: u64,
    /// The current episode's stream, after its world was drawn: its pushes.
    episode: Rng,
    /// The current episode's world (the nominal one before the first draw).
    pub world: WorldDraw,
}

impl Randomizer {
    /// Env `id`'s randomization in a run of `seed`; `None` when `cfg.randomize` draws nothing.
    pub fn new(cfg: &SimConfig, seed: u64, id: usize) -> Option<Self> {
        cfg.randomize.is_active().then(|| Self {
            nominal: cfg.clone(),
            worlds: Rng::derive(seed, WORLD_STREAMS + id as u64).next_u64(),
            noise: Rng::derive(seed, NOISE_STREAMS + id as u64).next_u64(),
            episode: Rng::new(0),
            world: WorldDraw::nominal(cfg),
        })
    }

    /// Draws episode `index`'s world and writes it into `cfg`, the env's config.
    pub fn draw(&mut self, index: u64, cfg: &mut SimConfig) {
        (self.world, self.episode) = self.world_of(index);
        self.world.configure(cfg, &self.nominal);
    }

    /// Episode `index`'s world, and its stream after the draw (its pushes').
    pub fn world_of(&self, index: u64) -> (WorldDraw, Rng) {
        let (n, c) = (&self.nominal, &self.nominal.randomize);
        let mut rng = Rng::derive(self.worlds, index);
        let span = |rng: &mut Rng, [lo, hi]: [f64; 2]| rng.range(lo, hi);
        let friction_scale = AreaKind::KINDS.map(|_| span(&mut rng, c.friction_scale));
        let chassis_mass = n.robot.chassis_mass * span(&mut rng, c.mass_scale);
        let com_offset = c.com_offset.map(|m| span(&mut rng, [-m, m]));
        let payload = span(&mut rng, c.payload);
        let wheel_radius = n.robot.wheel_radius * span(&mut rng, c.wheel_radius_scale);
        let motor_max_torque = n.robot.motor_max_torque * span(&mut rng, c.torque_scale);
        let motor_damping = n.robot.motor_damping * span(&mut rng, c.gain_scale);
        let [lo, hi] = c.latency;
        let command_latency = n.robot.command_latency + lo + rng.below(hi - lo + 1);
        let world = WorldDraw {
            friction_scale,
            chassis_mass,
            com_offset,
            payload,
            wheel_radius,
            motor_max_torque,
            motor_damping,
            command_latency,
            motor_time_constant: n.robot.motor_time_constant + span(&mut rng, c.time_constant),
            gravity: n.gravity * span(&mut rng, c.gravity_scale),
            imu_error_scale: span(&mut rng, c.imu_error_scale),
        };
        (world, rng)
    }

    /// The push due after `steps` decision steps of the episode, a horizontal impulse (x, z),
    /// N·s: every `push-interval` seconds, its size drawn from `push-impulse` and its
    /// direction uniform.
    pub fn push(&mut self, steps: u32) -> Option<[f64; 2]> {
        let c = &self.nominal.randomize;
        if !c.pushes() || steps == 0 {
            return None;
        }
        let every = (c.push_interval / self.nominal.decision_dt())
            .round()
            .max(1.0) as u32;
        if !steps.is_multiple_of(every) {
            return None;
        }
        let [lo, hi] = c.push_impulse;
        let size = self.episode.range(lo, hi);
        let angle = self
            .episode
            .range(-std::f64::consts::PI, std::f64::consts::PI);
        Some([size * angle.cos(), size * angle.sin()])
    }

    /// Tick `tick`'s observation noise, when any: the target's three coordinates' (m), then
    /// the three attitude angles' (rad).
    pub fn noise(&self, tick: u64) -> Option<[f64; 6]> {
        let c = &self.nominal.randomize;
        let (target, attitude) = (c.target_noise, c.attitude_noise);
        if target == 0.0 && attitude == 0.0 {
            return None;
        }
        let mut rng = Rng::derive(self.noise, tick);
        let sigma = [target, target, target, attitude, attitude, attitude];
        Some(sigma.map(|s| s * rng.normal()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::RandomizeConfig;

    fn randomized() -> SimConfig {
        let mut cfg = SimConfig {
            randomize: RandomizeConfig {
                friction_scale: [0.5, 1.25],
                mass_scale: [0.8, 1.5],
                com_offset: [0.01, 0.005, 0.02],
                payload: [0.0, 0.2],
                wheel_radius_scale: [0.9, 1.1],
                torque_scale: [0.5, 1.0],
                gain_scale: [0.1, 1.0],
                latency: [1, 3],
                time_constant: [0.0, 0.05],
                gravity_scale: [0.9, 1.1],
                imu_error_scale: [0.5, 2.0],
                target_noise: 0.01,
                attitude_noise: 0.02,
                push_impulse: [0.1, 0.3],
                push_interval: 1.0,
            },
            ..SimConfig::default()
        };
        cfg.robot.command_latency = 2;
        cfg.robot.motor_time_constant = 0.01;
        cfg
    }

    fn within(x: f64, [lo, hi]: [f64; 2]) -> bool {
        (lo..=hi).contains(&x)
    }

    #[test]
    fn every_term_is_drawn_within_its_range() {
        let cfg = randomized();
        let (c, r) = (&cfg.randomize, &cfg.robot);
        let mut rz = Randomizer::new(&cfg, 7, 3).expect("active");
        let mut latencies = std::collections::BTreeSet::new();
        for episode in 0..500 {
            let mut env_cfg = cfg.clone();
            rz.draw(episode, &mut env_cfg);
            let w = rz.world;
            assert!(
                w.friction_scale
                    .iter()
                    .all(|f| within(*f, c.friction_scale))
            );
            assert!(within(w.chassis_mass / r.chassis_mass, c.mass_scale));
            assert!((0..3).all(|i| w.com_offset[i].abs() <= c.com_offset[i]));
            assert!(within(w.payload, c.payload));
            assert!(within(
                w.wheel_radius / r.wheel_radius,
                c.wheel_radius_scale
            ));
            assert!(within(
                w.motor_max_torque / r.motor_max_torque,
                c.torque_scale
            ));
            assert!(within(w.motor_damping / r.motor_damping, c.gain_scale));
            assert!((3..=5).contains(&w.command_latency), "2 + [1, 3]");
            latencies.insert(w.command_latency);
            assert!(within(w.motor_time_constant, [0.01, 0.06]));
            assert!(within(w.gravity / 9.81, c.gravity_scale));
            assert!(within(w.imu_error_scale, c.imu_error_scale));
            let g = &env_cfg.imu.gyro;
            let nominal = &cfg.imu.gyro;
            assert_eq!(g.noise_density, nominal.noise_density * w.imu_error_scale);
            assert_eq!(env_cfg.robot.wheel_radius, w.wheel_radius);
            assert_eq!(env_cfg.gravity, w.gravity);
            let noise = rz.noise(episode).expect("noise on");
            assert!(noise[..3].iter().all(|n| n.abs() < 0.01 * 6.0));
            assert!(noise[3..].iter().all(|n| n.abs() < 0.02 * 6.0));
        }
        assert_eq!(
            latencies.len(),
            3,
            "both ends of the latency range are drawn"
        );
    }

    #[test]
    fn the_same_seed_draws_the_same_worlds_and_each_env_its_own() {
        let cfg = randomized();
        let worlds = |seed, id| {
            let mut rz = Randomizer::new(&cfg, seed, id).expect("active");
            (0..20)
                .map(|k| {
                    rz.draw(k, &mut cfg.clone());
                    (rz.world, rz.push(10), rz.noise(k))
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(worlds(7, 0), worlds(7, 0));
        assert_ne!(worlds(7, 0), worlds(7, 1));
        assert_ne!(worlds(7, 0), worlds(8, 0));
        // Episode k's world does not depend on the episodes drawn before it.
        let mut rz = Randomizer::new(&cfg, 7, 0).expect("active");
        rz.draw(12, &mut cfg.clone());
        assert_eq!(rz.world, worlds(7, 0)[12].0);
    }

    #[test]
    fn pushes_come_every_interval_with_a_size_in_range() {
        let cfg = randomized();
        let mut rz = Randomizer::new(&cfg, 1, 0).expect("active");
        rz.draw(0, &mut cfg.clone());
        // 1 s at 0.1 s per decision step: every 10 steps.
        let due: Vec<u32> = (0..35).filter(|s| rz.push(*s).is_some()).collect();
        assert_eq!(due, vec![10, 20, 30]);
        for _ in 0..100 {
            let [x, z] = rz.push(10).expect("due");
            assert!(within(x.hypot(z), [0.1, 0.3]));
        }
    }

    #[test]
    fn the_default_randomizes_nothing() {
        assert!(Randomizer::new(&SimConfig::default(), 1, 0).is_none());
        let nominal = WorldDraw::nominal(&SimConfig::default());
        let mut cfg = SimConfig::default();
        nominal.configure(&mut cfg, &SimConfig::default());
        assert_eq!(cfg, SimConfig::default());
        assert_eq!(nominal.values().len(), WorldDraw::columns().len());
    }
}
