//! `recorder-proc serve`: joins a run as one more reader of `telemetry` and `terrain`, like
//! the estimator, and records what it reads until the run asks its processes to stop.
//!
//! It never holds the run up: it only reads, its services drop the oldest sample when it
//! lags, and any error of its own ends this process alone, after closing the file.

use super::{describe, load_config, print_output};
use crate::options::RecordOptions;
use crate::recording::{Recording, Summary};
use crate::sample::{EstimateSample, RobotSample};
use common::ipc::{self, Bus, Receiver, Svc};
use common::wire::{EnvTick, TerrainEstimate, TerrainHeader, TickHeader};
use iceoryx2::port::listener::Listener;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long a wait for telemetry may last before the stop request is checked again.
const WAIT: Duration = Duration::from_millis(100);

/// `serve`'s arguments: the launcher's two, the file, and what to keep.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub join: common::cli::JoinArgs,
    /// The recording to write (.rrd); an existing file is replaced.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub options: RecordOptions,
}

pub fn execute(args: &ServeArgs) -> anyhow::Result<()> {
    let cfg = load_config(&args.join.config)?;
    let summary = record(&cfg, &args.join.run_id, &args.out, &args.options)?;
    print_output(&describe(&summary));
    Ok(())
}

/// Records run `run_id` into `out` until its stop request (or SIGINT/SIGTERM).
pub fn record(
    cfg: &common::Config,
    run_id: &str,
    out: &Path,
    options: &RecordOptions,
) -> anyhow::Result<Summary> {
    Serve::connect(cfg, run_id, out, options)?.run()
}

/// A recorder joined to a run: its node, ports and open recording. Its ports are tied to
/// the thread that connected (see `common::ipc`), so it runs there too.
pub struct Serve {
    bus: Bus,
    control: Listener<Svc>,
    telemetry: Receiver<EnvTick, TickHeader>,
    terrain: Receiver<TerrainEstimate, TerrainHeader>,
    recording: Recording,
}

impl Serve {
    /// Joins run `run_id` as node `recorder`, subscribes, and creates the file at `out`.
    pub fn connect(
        cfg: &common::Config,
        run_id: &str,
        out: &Path,
        options: &RecordOptions,
    ) -> anyhow::Result<Self> {
        let bus = Bus::connect(run_id, "recorder")?;
        let control = bus.control_listener()?;
        let telemetry = bus.receiver(&ipc::TELEMETRY, None)?;
        let terrain = bus.receiver(&ipc::TERRAIN, None)?;
        let recording = Recording::create(out, run_id, cfg, options)?;
        tracing::info!(
            envs = cfg.sim.num_envs(),
            every = options.every,
            out = %out.display(),
            "recorder serving"
        );
        Ok(Self {
            bus,
            control,
            telemetry,
            terrain,
            recording,
        })
    }

    /// Records until the run's stop request, logs what was delivered before it, and closes
    /// the file; the file is closed on an error too.
    pub fn run(mut self) -> anyhow::Result<Summary> {
        let read = (|| {
            while !self.bus.stop_requested(&self.control) {
                self.telemetry.wait(WAIT)?;
                self.drain()?;
            }
            self.drain()
        })();
        let finished = self.recording.finish();
        read?;
        let summary = finished?;
        tracing::info!(
            robot_ticks = summary.robot_ticks,
            estimate_ticks = summary.estimate_ticks,
            bytes = summary.bytes,
            "recorder done"
        );
        Ok(summary)
    }

    /// Logs every buffered telemetry tick, then every buffered terrain estimate.
    fn drain(&mut self) -> anyhow::Result<()> {
        let mut robots = Vec::new();
        while let Some(sample) = self.telemetry.try_recv()? {
            let tick = sample.user_header().tick;
            robots.clear();
            robots.extend(sample.payload().iter().map(RobotSample::from));
            drop(sample);
            self.recording.robots(tick, &robots)?;
        }
        let mut estimates = Vec::new();
        while let Some(sample) = self.terrain.try_recv()? {
            let tick = sample.user_header().tick;
            estimates.clear();
            estimates.extend(sample.payload().iter().map(EstimateSample::from));
            drop(sample);
            self.recording.estimates(tick, &estimates)?;
        }
        Ok(())
    }
}
