//! `lavatube evaluate`: policies on named worlds. Every policy drives the same seeded courses
//! (`EpisodeStart::Course`) in every world, alone in `sim-proc` with its mean action, so the
//! worlds and policies compare leg by leg; a world with `[sim.randomize]` ranges draws each
//! leg's world from them, the same draw for every policy. The table of success % and reach
//! time (mean ± 95 % CI over the episodes) is printed and written with its JSON and a chart.

mod table;
pub(super) mod worlds;

use super::reproduce::evaluation::{course_ticks, drive, drive_courses};
use super::reproduce::stages::{Weights, checkpoints_in, export};
use crate::error::UserError;
use anyhow::Context;
use common::config::{AreaKind, EpisodeStart, PolicySlot};
use common::{Config, run_dir};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use table::Row;

#[derive(Debug, clap::Args)]
pub struct EvaluateArgs {
    /// The policies: `.policy` files, checkpoints (`.ckpt`) or run directories (their general
    /// learner's newest checkpoint), each `LABEL=PATH` or `PATH` (labelled by its file name).
    #[arg(required = true)]
    pub policies: Vec<String>,
    /// The worlds: a TOML file of `[[world]]` tables, each a `name` and config fields
    /// (e.g. configs/worlds/robustness.toml).
    #[arg(long)]
    pub worlds: PathBuf,
    /// The config the worlds are laid over (the policies' training config); default: the
    /// built-in one.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Where the robots drive: a terrain kind's area (`flat`, `rough`, …) or `mixed` (the
    /// course across the kinds).
    #[arg(long, default_value = "mixed")]
    pub area: String,
    /// Episodes per policy and world.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..))]
    pub episodes: u64,
    /// Envs driving at once.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub envs: u64,
    /// The courses' first seed (default: the config's `run.seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Where the table (evaluation.md, .json), the chart (evaluation.png) and every drive's
    /// telemetry go.
    #[arg(long)]
    pub out: PathBuf,
}

/// A policy to evaluate: its label and where its actor is.
struct Policy {
    label: String,
    source: Weights,
}

pub fn evaluate(args: EvaluateArgs) -> anyhow::Result<ExitCode> {
    let mut base = match &args.config {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    if let Some(seed) = args.seed {
        base.run.seed = seed;
    }
    let area = AreaKind::ALL
        .into_iter()
        .find(|a| a.name() == args.area)
        .ok_or_else(|| {
            let names: Vec<_> = AreaKind::ALL.iter().map(|a| a.name()).collect();
            UserError(format!(
                "--area {}: use one of {}",
                args.area,
                names.join(", ")
            ))
        })?;
    let mut worlds = worlds::read(&args.worlds, &base)?;
    for w in &mut worlds {
        w.cfg.sim.only_in(area, args.envs as usize);
        w.cfg.sim.task.episodes = EpisodeStart::Course;
        w.cfg
            .validate()
            .map_err(|e| UserError(format!("world `{}` in {}: {e}", w.name, area.name())))?;
    }
    let policies = args
        .policies
        .iter()
        .map(|p| policy(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let labels: Vec<String> = policies.iter().map(|p| p.label.clone()).collect();
    if let Some(twice) = labels
        .iter()
        .find(|l| labels.iter().filter(|m| m == l).count() > 1)
    {
        return Err(UserError(format!(
            "two policies are labelled `{twice}`: name them LABEL=PATH"
        ))
        .into());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let weights = policies
        .iter()
        .map(|p| weights_of(p, &args.out, base.ppo.obs_clip))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut rows = Vec::new();
    for w in &worlds {
        let dir = args.out.join(&w.name);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let ticks = course_ticks(&w.cfg, args.episodes, args.envs);
        for (p, file) in policies.iter().zip(&weights) {
            let legs = drive_courses(&w.cfg, args.episodes, |cfg, part| {
                let csv = dir.join(format!("{}-{part}.csv", p.label));
                drive(cfg, file, ticks, &csv)?;
                Ok(csv)
            })?;
            let row = Row::of(&w.name, &p.label, &legs, w.cfg.sim.decision_dt());
            eprintln!("evaluate: {}", row.line());
            rows.push(row);
        }
    }
    let names: Vec<String> = worlds.iter().map(|w| w.name.clone()).collect();
    let title = format!(
        "at least {} episodes per cell on {} ground, courses from seed {}",
        args.episodes,
        area.name(),
        base.run.seed
    );
    print!("{title}\n\n{}", table::markdown(&rows, &names, &labels));
    table::write(&args.out, &title, &rows, &names, &labels)?;
    println!("written: {}", args.out.join("evaluation.md").display());
    Ok(ExitCode::SUCCESS)
}

/// A policy argument, `LABEL=PATH` or `PATH`, whose path exists: a `.policy` file, a
/// checkpoint, or a run directory (its general learner's newest checkpoint).
fn policy(arg: &str) -> anyhow::Result<Policy> {
    let (label, path) = match arg.split_once('=') {
        Some((label, path)) => (label.to_owned(), PathBuf::from(path)),
        None => {
            let path = PathBuf::from(arg);
            let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or(arg);
            (stem.to_owned(), path)
        }
    };
    let refuse = |what: String| UserError(format!("policy `{arg}`: {what}"));
    if label.is_empty() || label.contains(['/', '|']) {
        return Err(refuse("a label must be a plain name".into()).into());
    }
    if !path.exists() {
        return Err(refuse(format!("{} does not exist", path.display())).into());
    }
    let source = if path.is_dir() {
        let learner = run_dir::learner_dir(&path, PolicySlot::General);
        let newest = checkpoints_in(&learner).map_err(|e| {
            refuse(format!(
                "{} is not a run directory with a general learner's checkpoint ({e})",
                path.display()
            ))
        })?;
        Weights::Checkpoint(newest.last().map(|(_, c)| c.clone()).unwrap_or_default())
    } else {
        Weights::of_file(path)
    };
    Ok(Policy { label, source })
}

/// The `.policy` file of `p`: its own, or its checkpoint's exported into `out/policies`
/// first.
fn weights_of(p: &Policy, out: &Path, obs_clip: f64) -> anyhow::Result<PathBuf> {
    let ckpt = match &p.source {
        Weights::File(file) => return Ok(file.clone()),
        Weights::Checkpoint(ckpt) => ckpt,
    };
    let dir = out.join("policies");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let file = dir.join(format!("{}.policy", p.label));
    export(ckpt, &file, obs_clip)?;
    Ok(file)
}
