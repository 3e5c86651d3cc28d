//! `<slot>.check.csv`: observations and the actions the simulator's forward pass takes for
//! them, so a runtime on a robot can be checked against lavatube's before it drives.

use anyhow::Context;
use common::observation::OBS_TERMS;
use common::policy::Scratch;
use common::{ACT_DIM, OBS_DIM, Policy, Rng};
use std::fmt::Write as _;
use std::path::Path;

/// Observations as a robot meets them (targets within a metre, any attitude), with every
/// fourth row scaled far out so the normaliser's clip and the action clip are exercised.
fn observation(rng: &mut Rng, row: usize) -> [f32; OBS_DIM] {
    let t = [
        rng.range(-0.6, 0.6),
        rng.range(-0.2, 0.2),
        rng.range(-0.6, 0.6),
    ];
    let mut obs = [0.0f32; OBS_DIM];
    obs[..3].copy_from_slice(&t.map(|v| v as f32));
    obs[3] = (t[0].hypot(t[2])) as f32;
    for k in 0..3 {
        let angle = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
        obs[4 + 2 * k] = angle.cos() as f32;
        obs[5 + 2 * k] = angle.sin() as f32;
    }
    if row % 4 == 3 {
        let scale = 10f64.powf(rng.range(1.0, 4.0)) as f32;
        obs.iter_mut().for_each(|o| *o *= scale);
    }
    obs
}

/// Writes `rows` rows: the observation terms, then the clipped mean action.
pub fn write(policy: &Policy, limit: f32, rows: usize, path: &Path) -> anyhow::Result<()> {
    let mut text = String::new();
    let names: Vec<&str> = OBS_TERMS.iter().map(|t| t.name).collect();
    let _ = writeln!(text, "{},action_left,action_right", names.join(","));
    let mut rng = Rng::new(1);
    let mut scratch = Scratch::default();
    let mut action = [0.0f32; ACT_DIM];
    for row in 0..rows {
        let obs = observation(&mut rng, row);
        policy.mean_action(&obs, &mut action, &mut scratch);
        let cells: Vec<String> = obs
            .iter()
            .chain(&action.map(|a| a.clamp(-limit, limit)))
            .map(f32::to_string)
            .collect();
        let _ = writeln!(text, "{}", cells.join(","));
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}
