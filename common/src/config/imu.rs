//! `[sim.imu]`: the robot's MEMS IMU (gyroscope and accelerometer) and the orientation filter
//! that turns its readings into the pitch, yaw and roll a real robot would observe (SPEC S9's
//! "real IMU" next step; our extension). The defaults are the Bosch BMI088's datasheet
//! figures (BST-BMI088-DS001, rev. 1.9): gyro noise 0.014 °/s/√Hz, accelerometer noise
//! 175 µg/√Hz, gyro offset ±1 °/s, accelerometer offset ±20 mg (±2 mg after calibration),
//! gyro bias instability 2 °/h.

use super::ConfigError;
use super::range::{count_in, in_range};
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

/// The gyroscope, as a type: its errors' defaults and units (rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gyro;
/// The accelerometer, as a type: its errors' defaults and units (m/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accel;

/// One three-axis sensor's errors, `S` naming the sensor (and so its defaults and units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
#[serde(bound(serialize = "", deserialize = "SensorErrors<S>: Default"))]
pub struct SensorErrors<S> {
    /// White noise density, unit/√Hz (per-sample σ = density × √sample rate). [0, 1].
    pub noise_density: f64,
    /// Bias random walk, unit/√s: the bias's σ grows as this × √t. [0, 1].
    pub bias_walk: f64,
    /// Turn-on bias: each axis's bias at spawn is drawn uniformly within ± this, unit. [0, 10].
    pub turn_on_bias: f64,
    /// Scale error: each axis's gain is 1 + a uniform draw within ± this. [0, 0.2].
    pub scale_error: f64,
    /// Full-scale range: readings saturate at ± this, unit. (0, 1000].
    pub range: f64,
    /// Output resolution, bits over [−range, range]; 0 leaves readings unquantised. 0 ..= 32.
    pub bits: u32,
    #[serde(skip)]
    pub sensor: PhantomData<S>,
}

impl<S> SensorErrors<S> {
    /// Checks each field; `keys` names them in the config, in declaration order.
    fn validate(&self, keys: [&'static str; 6]) -> Result<(), ConfigError> {
        in_range(keys[0], self.noise_density, 0.0, 1.0)?;
        in_range(keys[1], self.bias_walk, 0.0, 1.0)?;
        in_range(keys[2], self.turn_on_bias, 0.0, 10.0)?;
        in_range(keys[3], self.scale_error, 0.0, 0.2)?;
        in_range(keys[4], self.range, 1e-6, 1000.0)?;
        count_in(keys[5], self.bits, 0, 32)
    }
}

/// The Mahony orientation filter's gains and its accelerometer gate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct FilterConfig {
    /// Proportional gain on the gravity-direction error, 1/s. [0, 100]. Default 1.
    pub kp: f64,
    /// Integral gain (gyro bias estimation), 1/s²; 0 turns the bias integral off. [0, 10]. Default 0.05.
    pub ki: f64,
    /// The accelerometer corrects the attitude only while | |a| − g | ≤ this × g. (0, 10]. Default 0.1.
    pub gate: f64,
    /// Gyro samples averaged at each spawn, the robot standing still, as the filter's first bias estimate; 0 skips it. 0 ..= 10000. Default 25.
    pub calibration_samples: usize,
}

/// The IMU and its filter.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct ImuConfig {
    /// Simulate the IMU even when neither `sim.observation` nor `estimator.signal` reads it,
    /// so telemetry records its filtered angles beside the true ones. Default false.
    pub simulate: bool,
    pub gyro: SensorErrors<Gyro>,
    pub accel: SensorErrors<Accel>,
    pub filter: FilterConfig,
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

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            kp: 1.0,
            ki: 0.05,
            gate: 0.1,
            calibration_samples: 25,
        }
    }
}

impl ImuConfig {
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        self.gyro.validate([
            "sim.imu.gyro.noise-density",
            "sim.imu.gyro.bias-walk",
            "sim.imu.gyro.turn-on-bias",
            "sim.imu.gyro.scale-error",
            "sim.imu.gyro.range",
            "sim.imu.gyro.bits",
        ])?;
        self.accel.validate([
            "sim.imu.accel.noise-density",
            "sim.imu.accel.bias-walk",
            "sim.imu.accel.turn-on-bias",
            "sim.imu.accel.scale-error",
            "sim.imu.accel.range",
            "sim.imu.accel.bits",
        ])?;
        in_range("sim.imu.filter.kp", self.filter.kp, 0.0, 100.0)?;
        in_range("sim.imu.filter.ki", self.filter.ki, 0.0, 10.0)?;
        in_range("sim.imu.filter.gate", self.filter.gate, 1e-6, 10.0)?;
        count_in(
            "sim.imu.filter.calibration-samples",
            self.filter.calibration_samples,
            0,
            10_000,
        )
    }
}
