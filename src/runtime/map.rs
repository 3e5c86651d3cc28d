//! A run's map (`map.png`): drawn from the sim's `track.csv` when the run ends, and again by
//! `lavatube map` (from the track, or from a telemetry CSV).

use common::config::{AreaKind, Rect, SimConfig};
use common::terrain::Terrain;
use common::track::TrackPoint;
use std::path::Path;

/// The areas the sim's envs use, named as the map labels them.
fn areas(sim: &SimConfig) -> Vec<(&'static str, Rect)> {
    let t = &sim.terrain;
    sim.envs
        .iter()
        .filter(|(_, n)| **n > 0)
        .filter_map(|(area, _)| match *area {
            AreaKind::Mixed => Some(("mixed course", t.mixed_area)),
            kind => t.area(kind).map(|r| (kind.name(), r)),
        })
        .collect()
}

/// Draws `track` on the floor of `sim` to `out`; returns the image size.
pub fn draw(sim: &SimConfig, track: &[TrackPoint], out: &Path) -> anyhow::Result<(usize, usize)> {
    let terrain = Terrain::build(&sim.terrain)?;
    common::map::draw(&terrain, &areas(sim), track, out).map_err(anyhow::Error::msg)
}

/// Draws the map of the run in `dir` from its `track.csv`.
pub fn draw_run(sim: &SimConfig, dir: &Path) -> anyhow::Result<std::path::PathBuf> {
    let track =
        common::track::read(&dir.join(common::run_dir::TRACK_CSV)).map_err(anyhow::Error::msg)?;
    let out = dir.join(common::run_dir::MAP_PNG);
    draw(sim, &track, &out)?;
    Ok(out)
}
