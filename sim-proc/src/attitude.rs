//! The robot's attitude from its IMU: a Mahony explicit complementary filter (R. Mahony,
//! T. Hamel, J.-M. Pflimlin, "Nonlinear Complementary Filters on the Special Orthogonal
//! Group", IEEE Trans. Automatic Control 53(5), 2008, eq. 32). The gyroscope is integrated;
//! the accelerometer's direction, taken as gravity's, pulls the estimated up axis toward it
//! with gain `kp`, and an integral with gain `ki` learns the gyroscope's bias. While the
//! specific force's magnitude is far from the world's g (a bump, a landing) the accelerometer
//! is ignored.
//! Yaw is unobservable from gravity: it is the integrated gyroscope alone, from the heading
//! the filter was started with.

use crate::imu::{Imu, ImuSample};
use common::Rng;
use common::config::{FilterConfig, ImuConfig};
use glam::{DQuat, DVec3};
use rapier3d::prelude::{RigidBody, Vector};

/// One robot's attitude estimate.
#[derive(Debug, Clone)]
pub struct Mahony {
    cfg: FilterConfig,
    /// Gravity's magnitude, m/s²: what the accelerometer gate compares against.
    g: f64,
    /// Body to world.
    q: DQuat,
    /// The gyroscope bias learned by the integral term, rad/s.
    bias: DVec3,
}

impl Mahony {
    /// A filter started at attitude `q` with no bias learned, in a world of gravity `g` m/s².
    pub fn new(cfg: &FilterConfig, g: f64, q: DQuat) -> Self {
        Self {
            cfg: cfg.clone(),
            g,
            q: q.normalize(),
            bias: DVec3::ZERO,
        }
    }

    /// The estimated attitude, body to world.
    pub fn attitude(&self) -> DQuat {
        self.q
    }

    /// The gyroscope bias the integral has learned, rad/s.
    pub fn bias(&self) -> DVec3 {
        self.bias
    }

    /// Advances the estimate by one reading taken `dt` seconds after the last.
    pub fn update(&mut self, s: &ImuSample, dt: f64) {
        let norm = s.accel.length();
        let mut correction = DVec3::ZERO;
        if norm > 0.0 && (norm - self.g).abs() <= self.cfg.gate * self.g {
            // Error between the measured up direction and the estimated one, both in the
            // body frame: their cross product turns the estimate toward the measurement.
            let measured = s.accel / norm;
            let estimated = self.q.inverse() * DVec3::Y;
            let error = measured.cross(estimated);
            self.bias -= self.cfg.ki * error * dt;
            correction = self.cfg.kp * error;
        }
        let omega = s.gyro - self.bias + correction;
        let angle = omega.length() * dt;
        if angle > 0.0 {
            self.q = (self.q * DQuat::from_axis_angle(omega / omega.length(), angle)).normalize();
        }
    }
}

/// A robot's IMU and the filter reading it, sampled after every physics step.
#[derive(Debug, Clone)]
pub struct Sensing {
    imu: Imu,
    filter: Mahony,
    /// The chassis's linear velocity at the last sample, m/s, for its acceleration.
    last_velocity: DVec3,
}

impl Sensing {
    /// The IMU of env `id` (its errors drawn from its own stream of the run `seed`) in a world
    /// of gravity `g` m/s².
    pub fn new(cfg: &ImuConfig, g: f64, seed: u64, id: usize) -> Self {
        Self {
            imu: Imu::new(cfg, Rng::derive(seed, IMU_STREAMS + id as u64)),
            filter: Mahony::new(&cfg.filter, g, DQuat::IDENTITY),
            last_velocity: DVec3::ZERO,
        }
    }

    /// Restarts the filter on a robot just placed at `body`'s pose: a robot set down knows
    /// its heading. Standing still for `calibration_samples` readings first, it takes their
    /// mean gyro rate as its first bias estimate. The sensor keeps its biases.
    pub fn place(&mut self, body: &RigidBody, gravity: Vector, dt: f64) {
        let rot = body.rotation().as_dquat();
        let n = self.filter.cfg.calibration_samples;
        let mut sum = DVec3::ZERO;
        for _ in 0..n {
            sum += self
                .imu
                .read(rot, DVec3::ZERO, DVec3::ZERO, gravity.as_dvec3(), dt)
                .gyro;
        }
        self.filter = Mahony::new(&self.filter.cfg, self.filter.g, rot);
        if n > 0 {
            self.filter.bias = sum / n as f64;
        }
        self.last_velocity = body.linvel().as_dvec3();
    }

    /// Moves the IMU into a world of gravity `g` m/s² whose sensors have `cfg`'s errors, drawn
    /// again (`[sim.randomize]`); the filter's attitude and learned bias carry on.
    pub fn retune(&mut self, cfg: &ImuConfig, g: f64) {
        self.imu.redraw(cfg);
        self.filter.g = g;
    }

    /// Samples the IMU on `body` `dt` seconds after the last sample and updates the filter.
    pub fn sense(&mut self, body: &RigidBody, gravity: Vector, dt: f64) {
        let velocity = body.linvel().as_dvec3();
        let accel = (velocity - self.last_velocity) / dt;
        self.last_velocity = velocity;
        let s = self.imu.read(
            body.rotation().as_dquat(),
            body.angvel().as_dvec3(),
            accel,
            gravity.as_dvec3(),
            dt,
        );
        self.filter.update(&s, dt);
    }

    /// The filter's attitude, body to world.
    pub fn attitude(&self) -> DQuat {
        self.filter.attitude()
    }
}

/// Env `id`'s IMU draws from random stream `IMU_STREAMS + id` of the run seed.
const IMU_STREAMS: u64 = 2 << 32;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::unity_euler;
    use crate::imu::tests::quiet;

    const DT: f64 = 0.02;
    const G: f64 = 9.81;
    const GRAVITY: DVec3 = DVec3::new(0.0, -G, 0.0);

    /// Angle between two attitudes, degrees.
    fn off_deg(a: DQuat, b: DQuat) -> f64 {
        a.angle_between(b).to_degrees()
    }

    /// Runs `seconds` of a still robot at `truth` through `imu` and `filter`.
    fn still(imu: &mut Imu, filter: &mut Mahony, truth: DQuat, seconds: f64) {
        for _ in 0..(seconds / DT).round() as usize {
            let s = imu.read(truth, DVec3::ZERO, DVec3::ZERO, GRAVITY, DT);
            filter.update(&s, DT);
        }
    }

    #[test]
    fn started_ten_degrees_off_it_converges_within_five_seconds_on_still_flat_ground() {
        let cfg = ImuConfig::default();
        let mut imu = Imu::new(&cfg, Rng::new(2));
        let truth = DQuat::IDENTITY;
        let start = DQuat::from_rotation_x(10f64.to_radians());
        let mut filter = Mahony::new(&cfg.filter, G, start);
        assert!((off_deg(filter.attitude(), truth) - 10.0).abs() < 1e-9);
        still(&mut imu, &mut filter, truth, 5.0);
        let off = off_deg(filter.attitude(), truth);
        assert!(off < 0.5, "{off:.3}° off after 5 s");
    }

    /// An IMU with no errors: the tests below add the one they are about.
    fn error_free() -> ImuConfig {
        ImuConfig {
            gyro: quiet(),
            accel: quiet(),
            ..ImuConfig::default()
        }
    }

    fn pitch_error_with_bias(ki: f64) -> (f64, DVec3) {
        let mut cfg = error_free();
        cfg.filter.ki = ki;
        let mut imu = Imu::new(&cfg, Rng::new(3));
        let truth = DQuat::IDENTITY;
        let mut filter = Mahony::new(&cfg.filter, G, truth);
        let bias = DVec3::new(0.02, 0.0, 0.0);
        for _ in 0..(120.0 / DT) as usize {
            let mut s = imu.read(truth, DVec3::ZERO, DVec3::ZERO, GRAVITY, DT);
            s.gyro += bias;
            filter.update(&s, DT);
        }
        let pitch = unity_euler(filter.attitude().as_quat())[0];
        (pitch.to_degrees().abs(), filter.bias())
    }

    #[test]
    fn the_bias_integral_absorbs_a_constant_gyro_bias() {
        // Proportional only: a standing error of bias / kp = 0.02 rad, 1.15°.
        let (without, _) = pitch_error_with_bias(0.0);
        assert!(
            (without - 0.02f64.to_degrees()).abs() < 0.01,
            "{without:.3}°"
        );
        let (with, learned) = pitch_error_with_bias(0.05);
        assert!(with < 0.1, "{with:.3}° with the integral");
        assert!((learned.x - 0.02).abs() < 1e-3, "{learned:?}");
    }

    #[test]
    fn a_spawn_calibration_starts_the_filter_near_the_gyros_turn_on_bias() {
        let cfg = ImuConfig::default();
        let mut sensing = Sensing::new(&cfg, G, 7, 0);
        let turn_on = sensing.imu.gyro_bias();
        assert!(
            turn_on.length() > 1e-3,
            "a turn-on bias to find: {turn_on:?}"
        );
        let mut world = rapier3d::prelude::PhysicsWorld::new();
        let body = world.insert_body(rapier3d::prelude::RigidBodyBuilder::dynamic());
        sensing.place(&world.bodies[body], world.gravity, DT);
        // 25 samples of 1.7e-3 rad/s noise: the mean is within about 1e-3 of the bias.
        let learned = sensing.filter.bias();
        assert!(
            (learned - turn_on).length() < 1.5e-3,
            "{learned:?} against {turn_on:?}"
        );
    }

    #[test]
    fn on_the_moon_the_gate_trusts_lunar_gravity_not_earths() {
        // A still robot at 1.62 m/s² reads a sixth of Earth's specific force: the filter
        // made for the Moon corrects a 10° start from it, one made for Earth ignores it all.
        let moon = 1.62;
        let cfg = error_free();
        let mut imu = Imu::new(&cfg, Rng::new(4));
        let start = DQuat::from_rotation_x(10f64.to_radians());
        let mut lunar = Mahony::new(&cfg.filter, moon, start);
        let mut earth = Mahony::new(&cfg.filter, G, start);
        for _ in 0..(5.0 / DT) as usize {
            let s = imu.read(
                DQuat::IDENTITY,
                DVec3::ZERO,
                DVec3::ZERO,
                DVec3::Y * -moon,
                DT,
            );
            lunar.update(&s, DT);
            earth.update(&s, DT);
        }
        assert!(off_deg(lunar.attitude(), DQuat::IDENTITY) < 0.5);
        assert!((off_deg(earth.attitude(), DQuat::IDENTITY) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn the_gate_ignores_a_two_g_jolt() {
        let cfg = error_free();
        let truth = DQuat::IDENTITY;
        let jolt = ImuSample {
            gyro: DVec3::ZERO,
            accel: DVec3::new(2.0 * 9.81, 9.81, 0.0),
        };
        let mut gated = Mahony::new(&cfg.filter, G, truth);
        gated.update(&jolt, DT);
        assert_eq!(gated.attitude(), truth);
        // Without the gate the same jolt tilts the estimate.
        let mut open = Mahony::new(
            &FilterConfig {
                gate: 10.0,
                ..cfg.filter.clone()
            },
            G,
            truth,
        );
        open.update(&jolt, DT);
        assert!(off_deg(open.attitude(), truth) > 0.5);
    }
}
