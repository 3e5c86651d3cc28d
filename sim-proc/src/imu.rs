//! A simulated MEMS IMU on the chassis (our extension toward SPEC S9's real IMU): a
//! three-axis gyroscope and accelerometer sampled every physics step, with white noise, a
//! bias random walk, a turn-on bias, a scale error, saturation and quantisation
//! (`[sim.imu]`). Each env draws from its own seeded stream, so replay stays bit-identical.
//!
//! Body frame as in `robot`: X through the axle, Y up, Z forward. The gyroscope measures the
//! chassis's angular velocity in that frame (rapier reports it in the world frame); the
//! accelerometer measures specific force, R⁻¹·(a − g), so a robot at rest reads +g on Y.

use common::Rng;
use common::config::{Accel, Gyro, ImuConfig, SensorErrors};
use glam::{DQuat, DVec3};

/// One axis triple of a sensor: its fixed errors drawn at spawn and its drifting bias.
#[derive(Debug, Clone)]
struct Sensor<S> {
    cfg: SensorErrors<S>,
    /// Turn-on bias plus the random walk so far, per axis.
    bias: DVec3,
    /// 1 + scale error, per axis.
    gain: DVec3,
}

impl<S: Clone> Sensor<S> {
    fn new(cfg: &SensorErrors<S>, rng: &mut Rng) -> Self {
        let mut draw = |bound: f64| DVec3::from_array([(); 3].map(|()| rng.range(-bound, bound)));
        let bias = draw(cfg.turn_on_bias);
        let gain = DVec3::ONE + draw(cfg.scale_error);
        Self {
            cfg: cfg.clone(),
            bias,
            gain,
        }
    }

    /// The reading of `truth` after `dt` seconds since the last one.
    fn read(&mut self, truth: DVec3, dt: f64, rng: &mut Rng) -> DVec3 {
        let mut normal = || DVec3::from_array([(); 3].map(|()| rng.normal()));
        self.bias += self.cfg.bias_walk * dt.sqrt() * normal();
        let white = self.cfg.noise_density / dt.sqrt() * normal();
        let raw = self.gain * truth + self.bias + white;
        let range = self.cfg.range;
        let clipped = raw.clamp(DVec3::splat(-range), DVec3::splat(range));
        if self.cfg.bits == 0 {
            return clipped;
        }
        let lsb = 2.0 * range / 2f64.powi(self.cfg.bits as i32);
        (clipped / lsb).round() * lsb
    }
}

/// One reading of both sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Angular velocity, body frame, rad/s.
    pub gyro: DVec3,
    /// Specific force, body frame, m/s².
    pub accel: DVec3,
}

/// The IMU of one robot.
#[derive(Debug, Clone)]
pub struct Imu {
    gyro: Sensor<Gyro>,
    accel: Sensor<Accel>,
    rng: Rng,
}

impl Imu {
    /// A fresh IMU: turn-on biases and scale errors drawn from `rng`, which it then owns.
    pub fn new(cfg: &ImuConfig, mut rng: Rng) -> Self {
        let gyro = Sensor::new(&cfg.gyro, &mut rng);
        let accel = Sensor::new(&cfg.accel, &mut rng);
        Self { gyro, accel, rng }
    }

    /// Reads the sensors on a body at attitude `rot` turning at `omega_world` (rad/s, world
    /// frame) with linear acceleration `accel_world` (m/s², world frame) under `gravity`,
    /// `dt` seconds after the last reading.
    pub fn read(
        &mut self,
        rot: DQuat,
        omega_world: DVec3,
        accel_world: DVec3,
        gravity: DVec3,
        dt: f64,
    ) -> ImuSample {
        let to_body = rot.inverse();
        let gyro = self.gyro.read(to_body * omega_world, dt, &mut self.rng);
        let accel = self
            .accel
            .read(to_body * (accel_world - gravity), dt, &mut self.rng);
        ImuSample { gyro, accel }
    }

    /// Draws the turn-on biases and scale errors of `cfg`'s sensors again from the IMU's own
    /// stream: the sensor of a world drawn by `[sim.randomize]`.
    pub fn redraw(&mut self, cfg: &ImuConfig) {
        self.gyro = Sensor::new(&cfg.gyro, &mut self.rng);
        self.accel = Sensor::new(&cfg.accel, &mut self.rng);
    }

    /// The gyroscope's current bias, rad/s (for tests and diagnostics).
    pub fn gyro_bias(&self) -> DVec3 {
        self.gyro.bias
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::marker::PhantomData;

    const DT: f64 = 0.02;
    const GRAVITY: DVec3 = DVec3::new(0.0, -9.81, 0.0);

    /// A sensor with no errors and a range too wide to saturate.
    pub(crate) fn quiet<S>() -> SensorErrors<S> {
        SensorErrors {
            noise_density: 0.0,
            bias_walk: 0.0,
            turn_on_bias: 0.0,
            scale_error: 0.0,
            range: 1000.0,
            bits: 0,
            sensor: PhantomData,
        }
    }

    /// Allan deviation of `x` (sampled every `DT`) at cluster length `m` samples.
    fn allan(x: &[f64], m: usize) -> f64 {
        let means: Vec<f64> = x
            .chunks_exact(m)
            .map(|c| c.iter().sum::<f64>() / m as f64)
            .collect();
        let sum: f64 = means.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
        (sum / (2.0 * (means.len() - 1) as f64)).sqrt()
    }

    #[test]
    fn a_still_gyro_has_the_configured_noise_density_at_one_second() {
        let cfg = ImuConfig::default();
        let mut imu = Imu::new(&cfg, Rng::new(5));
        // 2,000 s at 50 Hz: 2,000 one-second clusters, an estimate good to about 2 %.
        let xs: Vec<f64> = (0..100_000)
            .map(|_| {
                imu.read(DQuat::IDENTITY, DVec3::ZERO, DVec3::ZERO, GRAVITY, DT)
                    .gyro
                    .x
            })
            .collect();
        let adev = allan(&xs, 50);
        let want = cfg.gyro.noise_density;
        assert!(
            (adev / want - 1.0).abs() < 0.1,
            "ADEV(1 s) {adev:.3e} rad/s against {want:.3e}"
        );
    }

    #[test]
    fn the_bias_random_walk_grows_as_configured() {
        let cfg = ImuConfig {
            gyro: SensorErrors {
                bias_walk: 1e-3,
                ..quiet()
            },
            ..ImuConfig::default()
        };
        // 400 IMUs, 100 s each: the spread of their biases is bias_walk × √100.
        let biases: Vec<f64> = (0..400)
            .map(|seed| {
                let mut imu = Imu::new(&cfg, Rng::new(seed));
                for _ in 0..5000 {
                    imu.read(DQuat::IDENTITY, DVec3::ZERO, DVec3::ZERO, GRAVITY, DT);
                }
                imu.gyro_bias().y
            })
            .collect();
        let sd = (biases.iter().map(|b| b * b).sum::<f64>() / biases.len() as f64).sqrt();
        let want = 1e-3 * 100f64.sqrt();
        assert!((sd / want - 1.0).abs() < 0.1, "{sd:.3e} against {want:.3e}");
    }

    #[test]
    fn readings_are_in_the_body_frame_saturate_and_quantise() {
        let cfg = ImuConfig {
            gyro: SensorErrors {
                range: 2.0,
                bits: 4,
                ..quiet()
            },
            accel: quiet(),
            ..ImuConfig::default()
        };
        let mut imu = Imu::new(&cfg, Rng::new(1));
        // Nose up: turned −90° about X, the forward axis (Z) points up.
        let rot = DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        let s = imu.read(rot, DVec3::new(0.0, 0.3, 0.0), DVec3::ZERO, GRAVITY, DT);
        // Still: the accelerometer reads +g along the body axis that points up.
        let up_in_body = rot.inverse() * DVec3::Y;
        assert!(
            (s.accel - 9.81 * up_in_body).length() < 1e-9,
            "{:?}",
            s.accel
        );
        // 0.3 rad/s about world Y, in the body frame, on a grid of 4 / 16 = 0.25 rad/s.
        let want = rot.inverse() * DVec3::new(0.0, 0.3, 0.0);
        assert!((s.gyro - (want / 0.25).round() * 0.25).length() < 1e-12);
        let fast = imu.read(
            DQuat::IDENTITY,
            DVec3::new(9.0, -9.0, 0.0),
            DVec3::ZERO,
            GRAVITY,
            DT,
        );
        assert_eq!(fast.gyro, DVec3::new(2.0, -2.0, 0.0));
    }

    #[test]
    fn the_same_seed_gives_the_same_stream() {
        let cfg = ImuConfig::default();
        let run = |seed| {
            let mut imu = Imu::new(&cfg, Rng::new(seed));
            (0..100)
                .map(|i| {
                    imu.read(
                        DQuat::from_rotation_y(0.01 * f64::from(i)),
                        DVec3::new(0.1, 0.2, 0.3),
                        DVec3::X,
                        GRAVITY,
                        DT,
                    )
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(9), run(9));
        assert_ne!(run(9), run(10));
    }
}
