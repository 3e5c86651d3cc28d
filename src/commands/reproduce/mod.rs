//! `lavatube reproduce`: the paper's experiment as one resumable command (DESIGN §6).
//!
//! Stages, each in its own directory under `--out`, each skipped when its `stage.json` says
//! it finished (an unfinished one is redone from scratch):
//! a. `a-flat`: the initial flat model, from scratch (SPEC S6);
//! b. `b-general`: the general model on every terrain kind's area (the paper's flat + rough),
//!    warm-started from (a); no estimator runs in (a) or (b), where one general model acts;
//! c. `c-collect`: telemetry of the general model (mean actions), every area (SPEC S7);
//! d. `d-analysis`: Table 3 and Figs. 5-8 (`estimator-proc analyze`); with more kinds than
//!    the paper's two, the K-kind classifier named on this recording (`estimator-proc kinds`);
//! e. `e-specialists`: one specialist per kind (FTM and RTM on the paper's terrains)
//!    fine-tuned from (b) at once, each on the transitions the estimator (not the true area)
//!    assigns to its terrain, acting by switching (SPEC S8); with K kinds the estimator is
//!    stage d's classifier; those of `reproduce.fresh-specialists` start from new weights
//!    instead (EXPERIMENT E19). `e-select` (with `reproduce.specialist-candidates`): each
//!    specialist is the best on its own terrain's validation courses of the general model
//!    and stage e's milestones. `e-switch` (with `reproduce.switch-windows` or
//!    `switch-dwells`): the online window and dwell switching reads the ground with, the
//!    best on the mixed validation courses;
//! f. `f-eval`: success rate and reach time of the general model and every specialist in
//!    each area (Table 1), and of switching between the specialists with stage d's
//!    classifier, every model on the same seeded courses (`EpisodeStart::Course`), in every
//!    area and on the mixed course; `f-robustness` (with `reproduce.robustness-worlds`):
//!    the general model and switching on the mixed course in each world of the file
//!    (EXPERIMENT E22);
//! g. `report.md`: every table beside the paper's numbers, figures, learning curves, and the
//!    paper's claims about Table 1 checked leg by leg on the legs both models drove.
//!
//! Modules: [`pipeline`] runs the stages in order, [`stages`] holds the pipeline's setting
//! and keeps the stages' directories and done markers, [`evaluation`] drives the seeded
//! courses whose [`legs`] pair up, [`selection`] picks the specialists, [`tuning`] the
//! switch's window and dwell, [`robustness`] drives the other worlds, [`statistics`] and
//! [`checks`] compare the models, [`report`] writes the Markdown.

mod checks;
mod coverage;
pub(super) mod evaluation;
pub(super) mod legs;
mod pipeline;
mod report;
mod robustness;
mod selection;
pub(super) mod stages;
pub(super) mod statistics;
mod tuning;

use super::UserError;
use anyhow::Context;
use common::Config;
use common::config::PolicySlot;
use legs::Evaluated;
use stages::Pipeline;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct ReproduceArgs {
    /// The pipeline's config: its `[reproduce]` section sizes the stages, the rest applies to
    /// every stage.
    #[arg(long, default_value = "configs/paper.toml")]
    pub config: PathBuf,
    /// Output directory (stages are resumed from it).
    #[arg(long, default_value = "reproduce")]
    pub out: PathBuf,
    /// No progress bars (for logs and CI).
    #[arg(long)]
    pub quiet: bool,
    /// Repeat the pipeline with seeds `run.seed`, +1, …, each in `OUT/seed-<seed>/`, and
    /// report every number as mean ± 95 % CI.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=20))]
    pub seeds: u64,
    /// The output directory of another finished `reproduce --seeds N` over the same seeds
    /// (e.g. the truth-pose pipeline's, beside an IMU one): the report over seeds puts each of
    /// its numbers beside this run's.
    #[arg(long)]
    pub beside: Option<PathBuf>,
}

pub fn reproduce(args: ReproduceArgs) -> anyhow::Result<ExitCode> {
    let base = Config::load(&args.config)?;
    let out = std::path::absolute(&args.out)
        .with_context(|| format!("cannot resolve {}", args.out.display()))?;
    if base.run.learners != [PolicySlot::General]
        || base.run.init_from.is_some()
        || base.run.init_learning_rate.is_some()
    {
        return Err(UserError(
            "reproduce sets run.learners, run.init-from and run.init-learning-rate per stage: \
             leave them unset"
                .into(),
        )
        .into());
    }
    if let Some(file) = &base.reproduce.robustness_worlds {
        // Refused now, not after hours of training.
        let mut nominal = base.clone();
        nominal.sim.randomize = common::config::RandomizeConfig::default();
        super::evaluate::worlds::read(file, &nominal)?;
    }
    let seeds: Vec<u64> = (0..args.seeds)
        .map(|k| base.run.seed.wrapping_add(k))
        .collect();
    let beside = args
        .beside
        .as_deref()
        .map(|dir| finished_runs(dir, &seeds))
        .transpose()?;
    let mut runs = Vec::new();
    for &seed in &seeds {
        let mut cfg = base.clone();
        cfg.run.seed = seed;
        let dir = if args.seeds == 1 {
            out.clone()
        } else {
            out.join(format!("seed-{seed}"))
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let p = Pipeline {
            base: cfg,
            out: dir,
            quiet: args.quiet,
        };
        let cells = pipeline::run(&p)?;
        runs.push((p, cells));
    }
    if args.seeds > 1 {
        let path = out.join("report.md");
        std::fs::write(&path, report::seeds_report(&runs, beside.as_deref())?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("report over {} seeds: {}", args.seeds, path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// The finished pipelines of `seeds` in `dir`, a `reproduce --seeds N` output directory.
fn finished_runs(dir: &Path, seeds: &[u64]) -> anyhow::Result<Vec<(Pipeline, Vec<Evaluated>)>> {
    if seeds.len() < 2 {
        return Err(UserError(
            "--beside needs --seeds 2 or more: only the report over seeds sets runs side by side"
                .into(),
        )
        .into());
    }
    seeds
        .iter()
        .map(|seed| {
            let out = dir.join(format!("seed-{seed}"));
            let missing = UserError(format!(
                "--beside {}: {} has no finished pipeline of seed {seed}",
                dir.display(),
                out.display()
            ));
            let config = out.join(common::run_dir::CONFIG_TOML);
            if !config.is_file() {
                return Err(missing.into());
            }
            let p = Pipeline {
                base: Config::load(&config)?,
                out,
                quiet: true,
            };
            let cells = pipeline::evaluated_before(&p)?.ok_or(missing)?;
            Ok((p, cells))
        })
        .collect()
}

/// The table row of `claim` in the Markdown `md`, for tests of the reports.
#[cfg(test)]
fn row_of(md: &str, claim: &str) -> String {
    md.lines()
        .find(|l| l.starts_with(&format!("| {claim} |")))
        .unwrap_or_else(|| panic!("no row {claim} in\n{md}"))
        .to_string()
}
