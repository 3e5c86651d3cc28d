//! `lavatube map`: draw a run's map again, from its `track.csv` (the run directory), or from
//! a telemetry CSV the sim wrote (`run.telemetry-csv`, `sim-proc --telemetry`) and the config
//! of the floor it drove on.

use super::UserError;
use crate::runtime::map;
use common::{Config, TelemetryRow, run_dir};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct MapArgs {
    /// The run directory (its config.toml and track.csv): draws `<RUN_DIR>/map.png`.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = ["telemetry", "config", "run_id"])]
    pub run: Option<PathBuf>,
    /// The run of this id under `runs/` (the default `run.out-dir`): as `--run runs/<RUN_ID>`.
    #[arg(long, value_parser = common::cli::parse_run_id, conflicts_with_all = ["telemetry", "config"])]
    pub run_id: Option<String>,
    /// A telemetry CSV to draw instead (its paths classed by its `slot` and `estimate` columns;
    /// black in a recording without them).
    #[arg(long, requires = "config")]
    pub telemetry: Option<PathBuf>,
    /// The config the telemetry was recorded with (its floor and areas).
    #[arg(long, requires = "telemetry")]
    pub config: Option<PathBuf>,
    /// Where to write the PNG. Default: `map.png` in the run directory, or beside the telemetry.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn map_command(args: MapArgs) -> anyhow::Result<ExitCode> {
    let run = args.run.clone().or_else(|| {
        args.run_id
            .as_ref()
            .map(|id| PathBuf::from("runs").join(id))
    });
    let (cfg, track, out) = match (&run, &args.telemetry, &args.config) {
        (Some(dir), _, _) => {
            let cfg_path = dir.join(run_dir::CONFIG_TOML);
            let track_path = dir.join(run_dir::TRACK_CSV);
            if !cfg_path.is_file() || !track_path.is_file() {
                return Err(UserError(format!(
                    "--run {}: not a run directory with a track (needs config.toml and track.csv)",
                    dir.display()
                ))
                .into());
            }
            let track = common::track::read(&track_path).map_err(UserError)?;
            (Config::load(&cfg_path)?, track, dir.join(run_dir::MAP_PNG))
        }
        (None, Some(csv), Some(cfg)) => {
            let rows = TelemetryRow::read_csv(csv).map_err(|e| UserError(e.to_string()))?;
            let track = common::track::from_telemetry(&rows, common::track::STRIDE);
            (Config::load(cfg)?, track, csv.with_extension("png"))
        }
        _ => {
            return Err(UserError(
                "give --run RUN_DIR (or --run-id R), or --telemetry CSV with --config".into(),
            )
            .into());
        }
    };
    let out = args.out.unwrap_or(out);
    let (w, h) = map::draw(&cfg.sim, &track, &out)?;
    println!(
        "{} ({w}×{h} px, {} track points)",
        out.display(),
        track.len()
    );
    Ok(ExitCode::SUCCESS)
}
