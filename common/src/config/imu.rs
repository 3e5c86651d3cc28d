//! `[sim.imu]`: the robot's MEMS IMU (gyroscope and accelerometer) and the orientation filter
//! that turns its readings into the pitch, yaw and roll a real robot would observe (SPEC S9's
//! "real IMU" next step; our extension). The defaults are the Bosch BMI088's datasheet
//! figures (BST-BMI088-DS001, rev. 1.9): gyro noise 0.014 °/s/√Hz, accelerometer noise
//! 175 µg/√Hz, gyro offset ±1 °/s, accelerometer offset ±20 mg (±2 mg after calibration),
//! gyro bias instability 2 °/h.

use super::setting::{Setting, count, flag, real, settings};
use serde::{Deserialize, Serialize};
use std::marker::PhantomData;

/// Where the robot's attitude (θx, θy, θz) comes from, for the observation's six cos/sin
/// terms (SPEC S5, `sim.observation`) and for the estimator's sin θx (SPEC S7,
/// `estimator.signal`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AttitudeSource {
    /// The simulator's pose, noise-free (the paper's).
    #[default]
    Truth,
    /// The orientation filter run on the simulated IMU.
    Imu,
}

impl Setting for AttitudeSource {}

/// The gyroscope, as a type: its errors' defaults and units (rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gyro;
/// The accelerometer, as a type: its errors' defaults and units (m/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accel;

settings! {
    /// One three-axis sensor's errors, `S` naming the sensor (and so its defaults and units:
    /// "unit" is rad/s for the gyroscope, m/s² for the accelerometer).
    #[serde(default)]
    #[serde(bound(serialize = "", deserialize = "SensorErrors<S>: Default"))]
    pub struct SensorErrors<S>, required {
        /// White noise density (per-sample σ = density × √sample rate).
        pub noise_density: f64 => real(0.0, 1.0), "unit/√Hz", Research;
        /// Bias random walk: the bias's σ grows as this × √t.
        pub bias_walk: f64 => real(0.0, 1.0), "unit/√s", Research;
        /// Turn-on bias: each axis's bias at spawn is drawn uniformly within ± this.
        pub turn_on_bias: f64 => real(0.0, 10.0), "unit", Research;
        /// Scale error: each axis's gain is 1 + a uniform draw within ± this.
        pub scale_error: f64 => real(0.0, 0.2), "", Research;
        /// Full-scale range: readings saturate at ± this (unit: rad/s for the gyroscope, m/s² for
        /// the accelerometer).
        pub range: f64 => real(1e-6, 1000.0), "unit", Research;
        /// Output resolution over [−range, range]; 0 leaves readings unquantised.
        pub bits: u32 => count(0, 32), "bits", Research;
        /// The sensor, as a type; no setting.
        #[serde(skip)]
        pub sensor: PhantomData<S>;
    }
}

settings! {
    /// The Mahony orientation filter's gains and its accelerometer gate.
    pub struct FilterConfig {
        /// Proportional gain on the gravity-direction error.
        pub kp: f64 = 1.0 => real(0.0, 100.0), "1/s", Advanced;
        /// Integral gain (gyro bias estimation); 0 turns the bias integral off.
        pub ki: f64 = 0.05 => real(0.0, 10.0), "1/s²", Advanced;
        /// The accelerometer corrects the attitude only while | |a| − g | ≤ this × g.
        pub gate: f64 = 0.1 => real(1e-6, 10.0), "g", Advanced;
        /// Gyro samples averaged at each spawn, the robot standing still, as the filter's first
        /// bias estimate; 0 skips it.
        pub calibration_samples: usize = 25 => count(0, 10_000), "samples", Advanced;
    }
}

settings! {
    /// The IMU and its filter.
    pub struct ImuConfig {
        /// Simulate the IMU even when neither `sim.observation` nor `estimator.signal` reads it,
        /// so telemetry records its filtered angles beside the true ones.
        pub simulate: bool = false => flag(), "", Research;
        /// The gyroscope's errors (rad/s).
        pub gyro: SensorErrors<Gyro> = SensorErrors::<Gyro>::default();
        /// The accelerometer's errors (m/s²).
        pub accel: SensorErrors<Accel> = SensorErrors::<Accel>::default();
        /// The orientation filter.
        pub filter: FilterConfig = FilterConfig::default();
    }
}

const DEG: f64 = std::f64::consts::PI / 180.0;
const G: f64 = 9.81;

impl Default for SensorErrors<Gyro> {
    fn default() -> Self {
        Self {
            noise_density: 0.014 * DEG,
            // Interpretation: the bias drifts by the datasheet's bias instability (2 °/h)
            // over 100 s.
            bias_walk: 2.0 / 3600.0 * DEG / 10.0,
            turn_on_bias: 1.0 * DEG,
            scale_error: 0.01,
            range: 500.0 * DEG,
            bits: 16,
            sensor: PhantomData,
        }
    }
}

impl Default for SensorErrors<Accel> {
    fn default() -> Self {
        Self {
            noise_density: 175e-6 * G,
            // Interpretation, as for the gyro: 0.1 mg over 100 s.
            bias_walk: 0.1e-3 * G / 10.0,
            // Interpretation: what a six-position calibration leaves of the ±20 mg zero-g
            // offset; uncalibrated, it alone tilts the estimate by up to 1.1°.
            turn_on_bias: 2e-3 * G,
            scale_error: 0.01,
            range: 6.0 * G,
            bits: 16,
            sensor: PhantomData,
        }
    }
}
