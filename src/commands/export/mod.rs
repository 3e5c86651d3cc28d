//! `lavatube export`: what a robot needs to drive as the simulator drives, outside lavatube.
//! Each actor as ONNX (normaliser and clips inside, [`crate::onnx`]) and as `.policy`, rows of
//! observations with the actions the simulator's forward pass takes for them (to check a
//! runtime against), and `controller.toml`: the control period, the action, the observation
//! terms, the attitude filter and the switch's settings, with the terrain model beside it.

mod check;
mod controller;

use super::reproduce::stages::{Weights, checkpoints_in, export};
use crate::error::UserError;
use crate::onnx::{self, Described};
use anyhow::Context;
use common::config::{Acting, PolicySlot};
use common::observation::OBS_TERMS;
use common::{ACT_DIM, Config, OBS_DIM, Policy, run_dir};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// A run directory (each slot's frozen checkpoint or its learner's newest, with the run's
    /// config.toml), a
    /// checkpoint (`.ckpt`) or a `.policy` file (exported as the general model).
    pub source: PathBuf,
    /// The directory to write into (created; files of the same names are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// The config a checkpoint or `.policy` was trained with (default: the built-in one); a
    /// run directory brings its own.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Rows of observations and the simulator's actions written beside each actor.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub check_rows: u64,
}

/// One actor to export: its slot, and where its weights come from.
struct Actor {
    slot: PolicySlot,
    weights: Weights,
}

pub fn export_command(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let (cfg, actors) = sources(&args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let mut written = Vec::new();
    for a in &actors {
        let file = args.out.join(format!("{}.policy", a.slot.name()));
        match &a.weights {
            Weights::Checkpoint(ckpt) => export(ckpt, &file, cfg.ppo.obs_clip)?,
            Weights::File(src) if src != &file => {
                std::fs::copy(src, &file).with_context(|| {
                    format!("cannot copy {} to {}", src.display(), file.display())
                })?;
            }
            Weights::File(_) => {}
        }
        let bytes =
            std::fs::read(&file).with_context(|| format!("cannot read {}", file.display()))?;
        let policy = Policy::from_bytes(&bytes, &file).map_err(|e| UserError(e.to_string()))?;
        check_shape(&policy, &file)?;
        write_actor(&cfg, a.slot, &policy, &args)?;
        written.push(a.slot);
    }
    controller::write(&cfg, &written, &args.out)?;
    println!(
        "wrote {} actor{} ({}) and controller.toml to {}",
        written.len(),
        if written.len() == 1 { "" } else { "s" },
        written
            .iter()
            .map(|s| s.name())
            .collect::<Vec<_>>()
            .join(", "),
        args.out.display()
    );
    let e = &cfg.estimator;
    if cfg.sim.acting == Acting::Switch && e.model.is_none() && e.kinds_model.is_none() {
        println!(
            "note: the run switched on a terrain model its estimator fitted online, which no file \
             holds; name one with estimator.model or estimator.kinds-model to export it"
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The config and the actors `args.source` holds; a one-line refusal when it holds none.
fn sources(args: &ExportArgs) -> anyhow::Result<(Config, Vec<Actor>)> {
    let src = &args.source;
    if !src.exists() {
        return Err(UserError(format!("{} does not exist", src.display())).into());
    }
    if !src.is_dir() {
        let cfg = match &args.config {
            Some(path) => Config::load(path)?,
            None => Config::default(),
        };
        let actor = Actor {
            slot: PolicySlot::General,
            weights: Weights::of_file(src.clone()),
        };
        return Ok((cfg, vec![actor]));
    }
    if args.config.is_some() {
        return Err(UserError(format!(
            "--config: {} is a run directory and brings its own config.toml",
            src.display()
        ))
        .into());
    }
    let cfg_path = src.join(run_dir::CONFIG_TOML);
    if !cfg_path.is_file() {
        return Err(UserError(format!(
            "{} is not a run directory (no config.toml)",
            src.display()
        ))
        .into());
    }
    let cfg = Config::load(&cfg_path)?;
    if let Some(gone) = cfg.run.frozen.values().find(|c| !c.is_file()) {
        return Err(UserError(format!(
            "{}: its run.frozen checkpoint {} is gone",
            src.display(),
            gone.display()
        ))
        .into());
    }
    let actors: Vec<Actor> = PolicySlot::ALL
        .into_iter()
        .filter_map(|slot| {
            let checkpoint = match cfg.run.frozen.get(&slot) {
                Some(frozen) => frozen.clone(),
                None => {
                    checkpoints_in(&run_dir::learner_dir(src, slot))
                        .ok()?
                        .pop()?
                        .1
                }
            };
            let weights = Weights::Checkpoint(checkpoint);
            Some(Actor { slot, weights })
        })
        .collect();
    if actors.is_empty() {
        return Err(UserError(format!("{} holds no learner checkpoint", src.display())).into());
    }
    Ok((cfg, actors))
}

/// A policy that does not take lavatube's observation or give its action cannot drive.
fn check_shape(policy: &Policy, file: &Path) -> anyhow::Result<()> {
    let l = policy.layout();
    if l.obs_dim != OBS_DIM || l.act_dim != ACT_DIM {
        return Err(UserError(format!(
            "{}: a policy of {} observations and {} actions; lavatube's take {OBS_DIM} and give {ACT_DIM}",
            file.display(),
            l.obs_dim,
            l.act_dim
        ))
        .into());
    }
    Ok(())
}

/// `<slot>.onnx` and `<slot>.check.csv` for one actor.
fn write_actor(
    cfg: &Config,
    slot: PolicySlot,
    policy: &Policy,
    args: &ExportArgs,
) -> anyhow::Result<()> {
    let limit = cfg.sim.robot.action_limit as f32;
    let model = onnx::actor(policy, limit, &described(cfg, slot));
    let path = args.out.join(format!("{}.onnx", slot.name()));
    std::fs::write(&path, model).with_context(|| format!("cannot write {}", path.display()))?;
    let path = args.out.join(format!("{}.check.csv", slot.name()));
    check::write(policy, limit, args.check_rows as usize, &path)
}

/// The model's description and metadata: what each input column is, what the output is,
/// how often to run it, and which config and lavatube made it.
fn described(cfg: &Config, slot: PolicySlot) -> Described {
    let terms: Vec<String> = OBS_TERMS
        .iter()
        .map(|t| format!("{} [{}] ({})", t.name, t.unit, t.frame))
        .collect();
    let metadata = vec![
        ("lavatube.version", env!("CARGO_PKG_VERSION").to_string()),
        ("lavatube.slot", slot.name().to_string()),
        ("lavatube.config-crc32c", controller::digest(cfg)),
        ("observation", terms.join("; ")),
        (
            "action",
            "target angular velocity of the left and right wheel".to_string(),
        ),
        ("action.unit", "rad/s".to_string()),
        ("action.limit", cfg.sim.robot.action_limit.to_string()),
        ("control-period-s", cfg.sim.decision_dt().to_string()),
    ];
    Described {
        doc: format!(
            "lavatube {} actor: deterministic (mean) action for raw observations, every {} s",
            slot.name(),
            cfg.sim.decision_dt()
        ),
        metadata: metadata
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
    }
}
