//! `controller.toml`: the settings a robot's control loop needs beside the actors, taken from
//! the run's config, and the terrain model the switch classifies with, copied beside it.

use anyhow::Context;
use common::Config;
use common::config::{
    Acting, AttitudeSource, FilterConfig, MixtureFeature, OnPlacement, PolicySlot, WindowFeature,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The terrain model's file name in the export directory.
pub const TERRAIN_MODEL: &str = "terrain-model.json";

#[derive(Serialize)]
#[serde(rename_all = "kebab-case")]
struct Controller {
    lavatube_version: &'static str,
    /// CRC-32C of the resolved config, as a run directory stores it.
    config_crc32c: String,
    /// Seconds between decisions: one observation in, one action out.
    control_period_s: f64,
    /// Wheel commands are clipped to ±this, rad/s.
    action_limit: f64,
    /// Which actor drives: one slot, or `switch` between them on the terrain estimate.
    acting: Acting,
    /// Each exported actor's ONNX file.
    actors: BTreeMap<PolicySlot, String>,
    /// Where the attitude terms come from: the true pose or the IMU's filter.
    observation: AttitudeSource,
    gravity: f64,
    filter: FilterConfig,
    switch: Switch,
}

#[derive(Serialize)]
#[serde(rename_all = "kebab-case")]
struct Switch {
    /// Ticks an estimate must hold before the actor changes, and per slot when leaving it.
    dwell: usize,
    leave_dwell: BTreeMap<PolicySlot, usize>,
    /// The terrain model (copied beside this file), if the config names one.
    terrain_model: Option<String>,
    window: usize,
    features: Vec<WindowFeature>,
    feature: MixtureFeature,
    signal: AttitudeSource,
    min_speed: f64,
    settle_ticks: usize,
    on_placement: OnPlacement,
    stay_prob: f64,
    unknown_beyond: f64,
}

/// CRC-32C of the config as a run directory stores it, in hex.
pub fn digest(cfg: &Config) -> String {
    format!("{:08x}", crc32c::crc32c(cfg.to_toml().as_bytes()))
}

/// Writes `controller.toml` (and the terrain model, if any) for the exported `slots`.
pub fn write(cfg: &Config, slots: &[PolicySlot], out: &Path) -> anyhow::Result<()> {
    let e = &cfg.estimator;
    let model: Option<&PathBuf> = e.kinds_model.as_ref().or(e.model.as_ref());
    if let Some(m) = model {
        let to = out.join(TERRAIN_MODEL);
        std::fs::copy(m, &to).with_context(|| {
            format!(
                "cannot copy the terrain model {} to {}",
                m.display(),
                to.display()
            )
        })?;
    }
    let c = Controller {
        lavatube_version: env!("CARGO_PKG_VERSION"),
        config_crc32c: digest(cfg),
        control_period_s: cfg.sim.decision_dt(),
        action_limit: cfg.sim.robot.action_limit,
        acting: cfg.sim.acting,
        actors: slots
            .iter()
            .map(|s| (*s, format!("{}.onnx", s.name())))
            .collect(),
        observation: cfg.sim.observation,
        gravity: cfg.sim.gravity,
        filter: cfg.sim.imu.filter.clone(),
        switch: Switch {
            dwell: cfg.sim.switch_dwell,
            leave_dwell: cfg.sim.leave_dwell.clone(),
            terrain_model: model.map(|_| TERRAIN_MODEL.to_string()),
            window: e.online_window,
            features: e.features.clone(),
            feature: e.feature,
            signal: e.signal,
            min_speed: e.min_speed,
            settle_ticks: e.settle_ticks,
            on_placement: e.on_placement,
            stay_prob: e.stay_prob,
            unknown_beyond: e.unknown_beyond,
        },
    };
    let text = format!(
        "# What a robot's control loop runs, beside the actors: written by `lavatube export`.\n{}",
        toml::to_string_pretty(&c).context("cannot write controller.toml")?
    );
    let path = out.join("controller.toml");
    std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
}
