//! What the sim in a run publishes and records every tick, whoever acts (a policy or a gym
//! client): the `telemetry` service, the telemetry CSV, the track and the drawn worlds; and
//! the estimator's classes it reads back from `terrain`.

use crate::Fleet;
use crate::driver::Driver;
use crate::telemetry_csv::{TelemetryCsv, telemetry_row};
use crate::track::SimTrack;
use crate::worlds_csv::WorldsCsv;
use common::Config;
use common::config::{Acting, PolicySlot};
use common::ipc::{self, Bus, Receiver, Sender};
use common::wire::{self, EnvTick, TerrainEstimate, TerrainHeader, TickHeader};
use std::path::Path;
use std::time::Duration;

/// The files a sim in a run writes as it steps, each when asked for: the telemetry CSV
/// (`--telemetry`), the track (`--track`) and the drawn worlds (`--worlds`).
#[derive(Debug, Clone, Copy, Default)]
pub struct TickFiles<'a> {
    pub telemetry: Option<&'a Path>,
    pub track: Option<&'a Path>,
    pub worlds: Option<&'a Path>,
}

/// The sim's per-tick outputs: its services, its files and the estimator's classes.
pub struct TickOutputs {
    tele_tx: Sender<EnvTick, TickHeader>,
    terrain_rx: Receiver<TerrainEstimate, TerrainHeader>,
    csv: Option<TelemetryCsv>,
    track: Option<SimTrack>,
    worlds: Option<WorldsCsv>,
    /// The estimator's newest class per env (`CLASS_UNKNOWN` before its first estimate).
    pub classes: Vec<u8>,
    /// Whether the sim's policies act (not a gym client), so the CSV names their slots.
    policies_act: bool,
    /// Each env's class on the track: the kind its acting specialist is for, else the
    /// estimator's class.
    acted: Vec<u8>,
    ticks: Vec<EnvTick>,
    tick: u64,
}

impl TickOutputs {
    /// The run's `telemetry` and `terrain` services, and the `files` asked for.
    pub fn open(bus: &Bus, cfg: &Config, files: &TickFiles) -> anyhow::Result<Self> {
        let n = cfg.sim.num_envs();
        Ok(Self {
            tele_tx: bus
                .sender(&ipc::TELEMETRY, None, n)?
                .with_wake_interval(Duration::from_micros(cfg.sim.telemetry_notify_us as u64)),
            terrain_rx: bus.receiver(&ipc::TERRAIN, None)?,
            csv: files.telemetry.map(TelemetryCsv::append).transpose()?,
            track: files.track.map(|p| SimTrack::append(p, n)).transpose()?,
            worlds: files.worlds.map(|p| WorldsCsv::append(p, n)).transpose()?,
            classes: vec![wire::CLASS_UNKNOWN; n],
            policies_act: cfg.sim.acting != Acting::External,
            acted: vec![wire::CLASS_UNKNOWN; n],
            ticks: vec![EnvTick::default(); n],
            tick: 0,
        })
    }

    /// After a step of every env: its CSV rows, the estimator's newest classes, its track
    /// points and its telemetry tick (`env_steps` so far, acting with `policy_version`).
    pub fn publish(
        &mut self,
        fleet: &Fleet,
        driver: &Driver,
        env_steps: u64,
        policy_version: u32,
    ) -> anyhow::Result<()> {
        let n = fleet.len();
        if let Some(csv) = self.csv.as_mut() {
            for (i, (env, info)) in fleet.envs.iter().zip(&driver.infos).enumerate() {
                let estimate = PolicySlot::for_class(self.classes[i]).and_then(PolicySlot::kind);
                let slot = self.policies_act.then(|| driver.slot(i));
                csv.write(&telemetry_row(env, info, (estimate, slot)))?;
            }
        }
        if let Some(est) = self.terrain_rx.latest()? {
            for e in est.payload().iter().filter(|e| (e.env as usize) < n) {
                self.classes[e.env as usize] = e.class;
            }
        }
        if let Some(w) = self.worlds.as_mut() {
            w.see(&fleet.envs);
        }
        driver.env_ticks(fleet, &mut self.ticks);
        if let Some(t) = self.track.as_mut() {
            // The map shows the kind a specialist acted for, else the estimator's class.
            for (i, c) in self.acted.iter_mut().enumerate() {
                *c = driver
                    .slot(i)
                    .kind()
                    .map_or(self.classes[i], common::AreaKind::code);
            }
            t.see(&fleet.envs, &self.ticks, &self.acted);
        }
        let header = TickHeader {
            tick: self.tick,
            env_steps,
            policy_version,
            envs: n as u32,
            episodes: driver.episodes.episodes,
            successes: driver.episodes.successes,
            sent_ns: wire::monotonic_ns(),
            reach_ticks: driver.episodes.reach_ticks,
            reach_ticks_sq: driver.episodes.reach_ticks_sq,
        };
        self.tele_tx.send(header, &self.ticks)?;
        self.tick += 1;
        Ok(())
    }

    /// Wakes the telemetry readers and writes the track points taken so far: at each rollout
    /// chunk, and before the sim waits.
    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.tele_tx.flush()?;
        if let Some(t) = self.track.as_mut() {
            t.flush();
        }
        if let Some(w) = self.worlds.as_mut() {
            w.flush();
        }
        Ok(())
    }

    /// [`flush`](Self::flush), and the CSV's buffered rows: when the sim ends.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        self.flush()?;
        if let Some(csv) = self.csv.as_mut() {
            csv.flush()?;
        }
        Ok(())
    }
}
