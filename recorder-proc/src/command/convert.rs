//! `recorder-proc convert`: the same recording from a telemetry CSV the sim wrote
//! (`sim-proc --telemetry`, or `run.telemetry-csv` in a run), read row by row.
//!
//! The CSV has what the telemetry wire has, and nothing of the estimator: a converted
//! recording has no `window_std`, `class` or `posterior` series.

use super::{describe, load_config, print_output};
use crate::error::Result;
use crate::options::RecordOptions;
use crate::recording::{Recording, Summary};
use crate::sample::RobotSample;
use common::telemetry::TelemetryReader;
use std::path::{Path, PathBuf};

/// `convert`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {
    /// The lavatube config the telemetry was recorded with (its envs and floor).
    #[arg(long)]
    pub config: PathBuf,
    /// Telemetry CSV; its header is the `TelemetryRow` field names (as `sim-proc` writes it).
    #[arg(long)]
    pub telemetry: PathBuf,
    /// The recording to write (.rrd); an existing file is replaced.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub options: RecordOptions,
}

pub fn execute(args: &ConvertArgs) -> anyhow::Result<()> {
    let cfg = load_config(&args.config)?;
    let summary = convert(&cfg, &args.telemetry, &args.out, &args.options)?;
    print_output(&describe(&summary));
    Ok(())
}

/// Writes the recording of the telemetry CSV `telemetry` (recorded with `cfg`) to `out`.
/// Rows of one tick are logged together; the file is closed on every return.
pub fn convert(
    cfg: &common::Config,
    telemetry: &Path,
    out: &Path,
    options: &RecordOptions,
) -> Result<Summary> {
    // The header is checked before anything is written.
    let rows = TelemetryReader::open(telemetry)?;
    let name = telemetry.display().to_string();
    let mut recording = Recording::create(out, &name, cfg, options)?;
    let fed = feed(rows, &mut recording, cfg.sim.num_envs());
    let finished = recording.finish();
    fed?;
    finished
}

/// Logs the rows tick by tick (a tick is a run of rows with the same `tick`).
fn feed<R: std::io::Read>(
    rows: TelemetryReader<R>,
    recording: &mut Recording,
    envs: usize,
) -> Result<()> {
    let mut tick = None;
    let mut group: Vec<RobotSample> = Vec::new();
    let mut beyond = 0u64;
    for row in rows {
        let (_, row) = row?;
        if tick != Some(row.tick) {
            if let Some(t) = tick {
                recording.robots(t, &group)?;
            }
            group.clear();
            tick = Some(row.tick);
        }
        beyond += u64::from(row.env as usize >= envs);
        group.push(RobotSample::from(&row));
    }
    if let Some(t) = tick {
        recording.robots(t, &group)?;
    }
    if beyond > 0 {
        tracing::warn!(
            rows = beyond,
            envs,
            "rows of envs the config does not have were left out"
        );
    }
    Ok(())
}
