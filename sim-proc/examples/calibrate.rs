//! Terrain calibration (SPEC S1): mean rolling std of sin θx per area under the go-to-target
//! controller, for several windows, beside the paper's target ranges.
//!
//! `cargo run --release -p sim-proc --example calibrate [-- CONFIG.toml [TICKS]]`

use common::Config;
use common::config::{AreaKind, SimConfig};
use sim_proc::controllers::GoToController;
use sim_proc::standalone::drive;
use sim_proc::terrain::Terrain;
use sim_proc::{Fleet, SharedTerrain};

fn rolling_std_mean(series: &[Vec<f64>], w: usize, warmup: usize) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for s in series {
        for win in s[warmup.min(s.len())..].windows(w) {
            let m = win.iter().sum::<f64>() / w as f64;
            sum += (win.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (w - 1) as f64).sqrt();
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let cfg = match args.next() {
        Some(p) => Config::load(std::path::Path::new(&p))?,
        None => Config::default(),
    };
    let ticks: u64 = args.next().map(|t| t.parse()).transpose()?.unwrap_or(500);
    let windows = [10, 20, 40, 70, 100];
    let targets = [("flat", "0.02–0.05"), ("rough", "0.08–0.11")];
    let mut out = std::io::stdout().lock();
    use std::io::Write;
    writeln!(
        out,
        "| area | {} | SPEC S1 target |",
        windows.map(|w| format!("w={w}")).join(" | ")
    )?;
    writeln!(out, "|---|{}---|", "---|".repeat(windows.len()))?;
    for (k, (name, target)) in targets.iter().enumerate() {
        let sim = SimConfig {
            envs: [
                (AreaKind::Flat, if k == 0 { 4 } else { 0 }),
                (AreaKind::Rough, if k == 1 { 4 } else { 0 }),
            ]
            .into(),
            ..cfg.sim.clone()
        };
        let terrain = SharedTerrain::new(Terrain::build(&sim.terrain)?, sim.terrain.collider);
        let mut fleet = Fleet::new(&sim, &terrain, cfg.run.seed);
        let mut ctrl = GoToController::new(sim.robot.action_limit);
        let mut series = vec![Vec::new(); fleet.len()];
        let summary = drive(&mut fleet, &mut ctrl, ticks, |row, _| {
            series[row.env as usize].push(row.sin_pitch);
            Ok(())
        })?;
        eprintln!("{name}: {summary:?}");
        let cells = windows.map(|w| format!("{:.4}", rolling_std_mean(&series, w, 100)));
        writeln!(out, "| {name} | {} | {target} |", cells.join(" | "))?;
    }
    Ok(())
}
