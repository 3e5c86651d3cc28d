//! `lavatube reproduce`: the paper's experiment as one resumable command (DESIGN §6).
//!
//! Stages, each in its own directory under `--out`, each skipped when its `stage.json` says
//! it finished (an unfinished one is redone from scratch):
//! a. `a-flat`: the initial flat model, from scratch (SPEC S6);
//! b. `b-general`: the general model on flat + rough ground, warm-started from (a);
//! c. `c-collect`: telemetry of the general model (mean actions), both areas (SPEC S7);
//! d. `d-analysis`: Table 3 and Figs. 5–8 (`estimator-proc analyze`);
//! e. `e-specialists`: FTM and RTM fine-tuned from (b) at once, each on the transitions the
//!    estimator (not the true area) assigns to its terrain, acting by switching (SPEC S8);
//! f. `f-eval`: success rate and reach time of general, FTM and RTM in each area (Table 1),
//!    and of switching between FTM and RTM on stage d's terrain mixture;
//! g. `report.md`: every table beside the paper's numbers, figures and learning curves.

use super::UserError;
use super::run::{execute, learner_dir};
use crate::supervise;
use anyhow::Context;
use common::Config;
use common::config::{Acting, AreaKind, PolicySlot};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

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
}

/// One cell of the paper's Table 1: success %, mean reach time s, its std.
type PaperCell = (f64, f64, f64);

/// SPEC S8's Table 1 (50 trials per cell), per model: flat area, rough area.
const PAPER_TABLE_1: [(&str, [PaperCell; 2]); 3] = [
    ("general", [(100.0, 5.90, 2.54), (88.0, 10.51, 7.35)]),
    ("FTM", [(98.0, 5.47, 1.64), (76.0, 9.63, 4.29)]),
    ("RTM", [(98.0, 8.33, 5.92), (96.0, 8.96, 5.74)]),
];

/// Where stage f evaluates every model: SPEC S8's two areas, then the mixed course.
const EVAL_AREAS: [AreaKind; 3] = [AreaKind::Flat, AreaKind::Rough, AreaKind::Mixed];

/// Stage f's guess at the ticks an evaluation episode lasts, to size its runs: trained
/// models reach the target in about 40 (3.5-4 s at 0.1 s per tick).
const EPISODE_TICKS_GUESS: u64 = 50;

/// SPEC S7's Table 3: window, accuracy %.
const PAPER_TABLE_3: [(u64, f64); 4] = [(10, 61.13), (20, 70.73), (40, 85.87), (70, 98.79)];

/// One evaluation cell: a model in an area.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct Cell {
    episodes: u64,
    successes: u64,
    /// Reach time of successful episodes, seconds.
    mean_reach_s: f64,
    std_reach_s: f64,
}

impl Cell {
    fn success_pct(&self) -> f64 {
        100.0 * self.successes as f64 / self.episodes.max(1) as f64
    }

    /// `mean (std)` of the reach time, or `-` when no episode succeeded.
    fn reach(&self) -> String {
        if self.successes == 0 {
            "-".into()
        } else {
            format!("{:.2} ({:.2})", self.mean_reach_s, self.std_reach_s)
        }
    }
}

/// Episode outcomes in a telemetry CSV (`sim-proc --telemetry`): each episode's length
/// from its first row to the row that ends it; reach times are successful episodes' lengths.
fn episodes_in(path: &Path, decision_dt: f64) -> anyhow::Result<Cell> {
    let mut reader =
        csv::Reader::from_path(path).with_context(|| format!("cannot read {}", path.display()))?;
    let headers = reader.headers()?.clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .with_context(|| format!("{}: no `{name}` column", path.display()))
    };
    let (env, terminated, truncated, success) = (
        col("env")?,
        col("terminated")?,
        col("truncated")?,
        col("success")?,
    );
    let mut length: Vec<u64> = Vec::new();
    let (mut episodes, mut reach) = (0u64, Vec::new());
    for row in reader.records() {
        let row = row?;
        let e: usize = row[env].parse().context("env")?;
        if e >= length.len() {
            length.resize(e + 1, 0);
        }
        length[e] += 1;
        let flag = |i: usize| &row[i] == "true" || &row[i] == "1";
        if flag(terminated) || flag(truncated) {
            episodes += 1;
            if flag(success) {
                reach.push(length[e] as f64 * decision_dt);
            }
            length[e] = 0;
        }
    }
    let n = reach.len().max(1) as f64;
    let mean = reach.iter().sum::<f64>() / n;
    let var = reach.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n;
    Ok(Cell {
        episodes,
        successes: reach.len() as u64,
        mean_reach_s: mean,
        std_reach_s: var.sqrt(),
    })
}

/// The pipeline's directories and binaries.
struct Pipeline {
    base: Config,
    out: PathBuf,
    quiet: bool,
}

impl Pipeline {
    fn stage_dir(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }

    fn done(&self, name: &str) -> bool {
        self.stage_dir(name).join("stage.json").is_file()
    }

    fn finish(&self, name: &str, what: serde_json::Value) -> anyhow::Result<()> {
        let p = self.stage_dir(name).join("stage.json");
        std::fs::write(&p, serde_json::to_string_pretty(&what)?)
            .with_context(|| format!("cannot write {}", p.display()))
    }

    /// Starts stage `name` afresh (an unfinished earlier attempt is removed).
    fn fresh(&self, name: &str) -> anyhow::Result<PathBuf> {
        let dir = self.stage_dir(name);
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .with_context(|| format!("cannot remove the unfinished {}", dir.display()))?;
        }
        Ok(dir)
    }

    /// The shared-memory run id of stage `name`: unique to this process, so two pipelines
    /// (two `--out` directories, or a test beside a long run) never meet on one bus.
    fn run_id(&self, name: &str) -> String {
        format!("{name}-{}", std::process::id())
    }

    fn say(&self, line: &str) {
        eprintln!("reproduce: {line}");
    }

    /// A training stage: `cfg` run as run `name` in the output directory.
    fn train(&self, name: &str, mut cfg: Config) -> anyhow::Result<()> {
        if self.done(name) {
            self.say(&format!("{name}: done before, skipped"));
            return Ok(());
        }
        self.fresh(name)?;
        cfg.run.out_dir = self.out.clone();
        cfg.validate()?;
        self.say(&format!(
            "{name}: {}, {} steps, learners {:?}",
            cfg.sim.describe_envs(),
            cfg.run.total_steps,
            cfg.run
                .learners
                .iter()
                .map(|s| s.name())
                .collect::<Vec<_>>()
        ));
        if !execute(&cfg, name, &self.run_id(name), self.quiet)? {
            anyhow::bail!("interrupted during stage {name}; run again to resume");
        }
        self.finish(name, serde_json::json!({ "stage": name }))
    }

    /// The newest checkpoint of stage `name`'s learner for `slot`.
    fn checkpoint(&self, name: &str, slot: PolicySlot) -> anyhow::Result<PathBuf> {
        let dir = learner_dir(&self.stage_dir(name), slot).join("checkpoints");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "ckpt"))
            .collect();
        files.sort();
        files
            .pop()
            .with_context(|| format!("no checkpoint in {}", dir.display()))
    }

    /// Exports a checkpoint's actor to `out` with `learner-proc export`.
    fn export(&self, ckpt: &Path, out: &Path) -> anyhow::Result<()> {
        let status = Command::new(supervise::locate("learner-proc")?)
            .arg("export")
            .arg(ckpt)
            .arg("--out")
            .arg(out)
            .args(["--obs-clip", &self.base.ppo.obs_clip.to_string()])
            .status()?;
        anyhow::ensure!(
            status.success(),
            "learner-proc export {} failed",
            ckpt.display()
        );
        Ok(())
    }

    /// `sim-proc` alone with a policy file: `steps` decision steps per env, telemetry to `csv`.
    fn drive(&self, cfg: &Config, weights: &Path, steps: u64, csv: &Path) -> anyhow::Result<()> {
        let dir = csv.parent().unwrap_or(Path::new("."));
        let cfg_path = csv.with_extension("toml");
        std::fs::write(&cfg_path, cfg.to_toml())
            .with_context(|| format!("cannot write {}", cfg_path.display()))?;
        let run = Command::new(supervise::locate("sim-proc")?)
            .arg("--config")
            .arg(&cfg_path)
            .args(["--controller", "policy", "--weights"])
            .arg(weights)
            .args(["--steps", &steps.to_string(), "--telemetry"])
            .arg(csv)
            .current_dir(dir)
            .output()?;
        let log = csv.with_extension("log");
        std::fs::write(&log, [run.stdout, run.stderr].concat())
            .with_context(|| format!("cannot write {}", log.display()))?;
        anyhow::ensure!(
            run.status.success(),
            "sim-proc on {} failed; see {}",
            weights.display(),
            log.display()
        );
        Ok(())
    }

    /// SPEC S8's switching policy in `area`: FTM and RTM served frozen, each env acting with
    /// the one its live terrain estimate points to (mean actions), through the full runtime
    /// with the estimator; runs until the cell has its episodes.
    fn switching(
        &self,
        area: AreaKind,
        frozen: &std::collections::BTreeMap<PolicySlot, PathBuf>,
        eval: &Path,
    ) -> anyhow::Result<Cell> {
        let r = &self.base.reproduce;
        let mut cfg = self.eval_in(area);
        cfg.run.learners.clear();
        cfg.run.frozen = frozen.clone();
        cfg.run.mode = common::config::LearnMode::Async;
        cfg.run.out_dir = eval.to_path_buf();
        cfg.sim.acting = Acting::Switch;
        cfg.sim.mean_actions = true;
        // SPEC S7-S8: the estimator classifies with stage d's mixture, fitted on both
        // terrains, and is not refitted: a fit on one area's windows alone would split that
        // terrain into two classes and hand half of it to the other specialist.
        cfg.estimator.model = Some(self.stage_dir("d-analysis").join("results.json"));
        cfg.estimator.refit_every = 0;
        cfg.run.total_steps = self.eval_ticks() * r.eval_envs as u64;
        cfg.validate()?;
        let mut parts = Vec::new();
        while merge(&parts).episodes < r.eval_episodes {
            let name = format!("switch-{}-{}", area.name(), parts.len());
            if !execute(&cfg, &name, &self.run_id(&name), self.quiet)? {
                anyhow::bail!("interrupted during {name}; run again to resume");
            }
            let path = eval.join(&name).join("summary.json");
            let s: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(&path)
                    .with_context(|| format!("cannot read {}", path.display()))?,
            )?;
            parts.push(Cell {
                episodes: s["episodes"].as_u64().unwrap_or(0),
                successes: s["successes"].as_u64().unwrap_or(0),
                mean_reach_s: s["reach_seconds"]["mean"].as_f64().unwrap_or(0.0),
                std_reach_s: s["reach_seconds"]["std"].as_f64().unwrap_or(0.0),
            });
            anyhow::ensure!(
                parts.last().is_some_and(|c| c.episodes > 0),
                "{name} ended no episode; see {}",
                path.display()
            );
            cfg.run.seed = cfg.run.seed.wrapping_add(1);
        }
        Ok(merge(&parts))
    }

    /// The base config with `flat` + `rough` envs.
    fn envs(&self, flat: usize, rough: usize) -> Config {
        let mut c = self.base.clone();
        c.sim.flat_envs = flat;
        c.sim.rough_envs = rough;
        c.sim.mixed_envs = 0;
        c
    }

    /// Stage f's config in `area`: `reproduce.eval-envs` envs, all there, on the
    /// evaluation's ground.
    fn eval_in(&self, area: AreaKind) -> Config {
        let r = &self.base.reproduce;
        let mut c = self.base.clone();
        c.sim.only_in(area, r.eval_envs);
        if let Some(scale) = r.eval_roughness_scale {
            c.sim.terrain.roughness_scale = scale;
        }
        c
    }

    /// Ticks per env of one evaluation run: enough for the cell's episodes at
    /// `EPISODE_TICKS_GUESS` ticks each, and for every env to end one episode however long
    /// it lasts. A cell short of its episodes runs again with the next seed.
    fn eval_ticks(&self) -> u64 {
        let r = &self.base.reproduce;
        (r.eval_episodes.div_ceil(r.eval_envs as u64) * EPISODE_TICKS_GUESS)
            .max(self.base.sim.task.longest_episode_ticks() + 1)
    }
}

pub fn reproduce(args: ReproduceArgs) -> anyhow::Result<ExitCode> {
    let base = Config::load(&args.config)?;
    let out = std::path::absolute(&args.out)
        .with_context(|| format!("cannot resolve {}", args.out.display()))?;
    if base.run.learners != [PolicySlot::General] || base.run.init_from.is_some() {
        return Err(UserError(
            "reproduce sets run.learners and run.init-from per stage: leave them unset".into(),
        )
        .into());
    }
    let mut runs = Vec::new();
    for k in 0..args.seeds {
        let mut cfg = base.clone();
        cfg.run.seed = base.run.seed.wrapping_add(k);
        let dir = if args.seeds == 1 {
            out.clone()
        } else {
            out.join(format!("seed-{}", cfg.run.seed))
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let p = Pipeline {
            base: cfg,
            out: dir,
            quiet: args.quiet,
        };
        let cells = pipeline(&p)?;
        runs.push((p, cells));
    }
    if args.seeds > 1 {
        let path = out.join("report.md");
        std::fs::write(&path, seeds_report(&runs)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("report over {} seeds: {}", args.seeds, path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// An evaluation cell of a model in an area.
type Evaluated = (String, AreaKind, Cell);

/// One seed's pipeline, stages a–g in `p.out`.
fn pipeline(p: &Pipeline) -> anyhow::Result<Vec<Evaluated>> {
    let base = &p.base;
    let out = &p.out;
    let r = &base.reproduce;
    std::fs::write(out.join("config.toml"), base.to_toml())?;

    let mut a = p.envs(r.flat_envs, 0);
    a.run.total_steps = r.flat_steps;
    p.train("a-flat", a)?;

    let mut b = p.envs(r.envs_per_area, r.envs_per_area);
    b.run.total_steps = r.general_steps;
    b.run.init_from = Some(p.checkpoint("a-flat", PolicySlot::General)?);
    p.train("b-general", b)?;

    let policies = p.stage_dir("policies");
    std::fs::create_dir_all(&policies)?;
    let general = policies.join("general.policy");
    p.export(&p.checkpoint("b-general", PolicySlot::General)?, &general)?;

    let traces = p.stage_dir("c-collect").join("traces.csv");
    if !p.done("c-collect") {
        std::fs::create_dir_all(p.fresh("c-collect")?)?;
        p.say("c-collect: the general model in both areas (SPEC S7)");
        p.drive(
            &p.envs(r.envs_per_area, r.envs_per_area),
            &general,
            r.collect_steps,
            &traces,
        )?;
        p.finish("c-collect", serde_json::json!({ "traces": traces }))?;
    }

    let analysis = p.stage_dir("d-analysis");
    if !p.done("d-analysis") {
        p.fresh("d-analysis")?;
        p.say("d-analysis: Table 3, Figs. 5-8");
        let windows = base
            .estimator
            .windows
            .iter()
            .map(|w| w.to_string())
            .collect::<Vec<_>>()
            .join(",");
        let status = Command::new(supervise::locate("estimator-proc")?)
            .arg("analyze")
            .arg(&traces)
            .args(["--windows", &windows, "--out"])
            .arg(&analysis)
            .arg("--config")
            .arg(out.join("config.toml"))
            .status()?;
        anyhow::ensure!(status.success(), "estimator-proc analyze failed");
        p.finish("d-analysis", serde_json::json!({ "windows": windows }))?;
    }

    let mut e = p.envs(r.envs_per_area, r.envs_per_area);
    e.run.total_steps = r.finetune_steps;
    e.run.learners = vec![PolicySlot::Flat, PolicySlot::Rough];
    e.run.init_from = Some(p.checkpoint("b-general", PolicySlot::General)?);
    e.sim.acting = Acting::Switch;
    if let Some(scale) = r.finetune_roughness_scale {
        e.sim.terrain.roughness_scale = scale;
    }
    if let Some(lr) = r.finetune_learning_rate {
        e.ppo.learning_rate = lr;
    }
    p.train("e-specialists", e)?;
    let models = [
        ("general", general),
        ("FTM", policies.join("ftm.policy")),
        ("RTM", policies.join("rtm.policy")),
    ];
    p.export(
        &p.checkpoint("e-specialists", PolicySlot::Flat)?,
        &models[1].1,
    )?;
    p.export(
        &p.checkpoint("e-specialists", PolicySlot::Rough)?,
        &models[2].1,
    )?;

    let eval = p.stage_dir("f-eval");
    let cells_path = eval.join("cells.json");
    let cells: Vec<(String, AreaKind, Cell)> = if p.done("f-eval") {
        serde_json::from_str(&std::fs::read_to_string(&cells_path)?)?
    } else {
        std::fs::create_dir_all(p.fresh("f-eval")?)?;
        let mut cells = Vec::new();
        for (name, weights) in &models {
            for area in EVAL_AREAS {
                let mut cfg = p.eval_in(area);
                let mut cell = Cell {
                    episodes: 0,
                    successes: 0,
                    mean_reach_s: 0.0,
                    std_reach_s: 0.0,
                };
                let mut parts = Vec::new();
                // More seeds until the cell has its episodes.
                while cell.episodes < r.eval_episodes {
                    let csv = eval.join(format!(
                        "{}-{}-{}.csv",
                        name.to_lowercase(),
                        area.name(),
                        parts.len()
                    ));
                    p.drive(&cfg, weights, p.eval_ticks(), &csv)?;
                    let part = episodes_in(&csv, cfg.sim.decision_dt())?;
                    anyhow::ensure!(part.episodes > 0, "{} holds no episode", csv.display());
                    parts.push(part);
                    cell = merge(&parts);
                    cfg.run.seed = cfg.run.seed.wrapping_add(1);
                }
                p.say(&format!(
                    "f-eval: {name} on {} ground: {:.1}% of {} episodes, reach s {}",
                    area.name(),
                    cell.success_pct(),
                    cell.episodes,
                    cell.reach()
                ));
                cells.push((name.to_string(), area, cell));
            }
        }
        let frozen = [
            (
                PolicySlot::Flat,
                p.checkpoint("e-specialists", PolicySlot::Flat)?,
            ),
            (
                PolicySlot::Rough,
                p.checkpoint("e-specialists", PolicySlot::Rough)?,
            ),
        ];
        for area in EVAL_AREAS {
            let cell = p.switching(area, &frozen.clone().into(), &eval)?;
            p.say(&format!(
                "f-eval: switching on {} ground: {:.1}% of {} episodes, reach s {}",
                area.name(),
                cell.success_pct(),
                cell.episodes,
                cell.reach()
            ));
            cells.push(("switching".into(), area, cell));
        }
        std::fs::write(&cells_path, serde_json::to_string_pretty(&cells)?)?;
        p.finish("f-eval", serde_json::json!({ "cells": cells.len() }))?;
        cells
    };

    let report = report(p, &cells)?;
    let path = out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    println!("report: {}", path.display());
    Ok(cells)
}

/// Mean and half-width of the 95 % confidence interval of the mean (Student's t).
fn mean_ci(xs: &[f64]) -> (f64, f64) {
    const T975: [f64; 19] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093,
    ];
    let n = xs.len();
    let mean = xs.iter().sum::<f64>() / n.max(1) as f64;
    if n < 2 {
        return (mean, f64::NAN);
    }
    let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    let t = T975.get(n - 2).copied().unwrap_or(1.96);
    (mean, t * sd / (n as f64).sqrt())
}

/// `mean ± ci` over seeds.
fn pm(xs: &[f64], digits: usize) -> String {
    let (m, h) = mean_ci(xs);
    format!("{m:.digits$} ± {h:.digits$}")
}

/// The report over several seeds: every number as mean ± 95 % CI.
fn seeds_report(runs: &[(Pipeline, Vec<Evaluated>)]) -> anyhow::Result<String> {
    let mut md = format!(
        "# lavatube reproduce over {} seeds\n\n\
         Every number is the mean over seeds ± the half-width of its 95 % confidence interval \
         (Student's t); each seed's own report is in `seed-<seed>/report.md`.\n\n\
         ## Table 1\n\n\
         | model | area | success % | reach s (mean) | paper: success % |\n\
         |---|---|---:|---:|---:|\n",
        runs.len()
    );
    let Some((_, first)) = runs.first() else {
        return Ok(md);
    };
    for (i, (name, area, _)) in first.iter().enumerate() {
        let cells: Vec<&Cell> = runs
            .iter()
            .filter_map(|(_, c)| c.get(i).map(|c| &c.2))
            .collect();
        let success: Vec<f64> = cells.iter().map(|c| c.success_pct()).collect();
        let reach: Vec<f64> = cells
            .iter()
            .filter(|c| c.successes > 0)
            .map(|c| c.mean_reach_s)
            .collect();
        let paper = paper_cell(name, *area).map_or("-".into(), |(s, _, _)| format!("{s:.1}"));
        md += &format!(
            "| {name} | {} | {} | {} | {paper} |\n",
            area.name(),
            pm(&success, 1),
            if reach.is_empty() {
                "-".into()
            } else {
                pm(&reach, 2)
            }
        );
    }
    md +=
        "\n## Table 3: accuracy by window\n\n| window | accuracy % | paper % |\n|---:|---:|---:|\n";
    let mut by_window: std::collections::BTreeMap<u64, Vec<f64>> = Default::default();
    for (p, _) in runs {
        let path = p.stage_dir("d-analysis").join("results.json");
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&path)
                .with_context(|| format!("cannot read {}", path.display()))?,
        )?;
        for w in json["windows"].as_array().into_iter().flatten() {
            if let (Some(win), Some(acc)) = (w["window"].as_u64(), w["accuracy"].as_f64()) {
                by_window.entry(win).or_default().push(100.0 * acc);
            }
        }
    }
    for (w, accs) in by_window {
        let paper = PAPER_TABLE_3
            .iter()
            .find(|(pw, _)| *pw == w)
            .map_or("-".into(), |(_, a)| format!("{a:.2}"));
        md += &format!("| {w} | {} | {paper} |\n", pm(&accs, 2));
    }
    Ok(md)
}

/// Issue 7's claims about Table 1, each checked on this run's cells: a model "at least as
/// good" has the higher success rate, or the same one and a mean reach time no longer. Each
/// row gives the success-rate difference (Wald) and the reach-time advantage (Welch) with
/// their 95 % intervals. A claim that fails on the point estimates reads "no" only when the
/// first model is worse beyond the noise (a success rate lower, or one not higher and a reach
/// time longer, beyond their intervals), else "within noise"; "better than" needs a success
/// rate higher beyond the noise, or one no lower and a reach time shorter beyond the noise.
fn shape_checks(cells: &[Evaluated]) -> String {
    let find = |model: &str, area: AreaKind| {
        cells
            .iter()
            .find(|(m, a, _)| m == model && *a == area)
            .map(|c| c.2)
    };
    let best_single = |area: AreaKind| {
        ["general", "FTM", "RTM"]
            .into_iter()
            .filter_map(|m| find(m, area).map(|c| (m, c)))
            .max_by(|(_, a), (_, b)| rank(a).total_cmp(&rank(b)))
    };
    let mut claims = vec![
        ("FTM", "general", AreaKind::Flat, false),
        ("RTM", "general", AreaKind::Rough, false),
    ];
    for area in EVAL_AREAS {
        if let Some((m, _)) = best_single(area) {
            claims.push(("switching", m, area, false));
        }
    }
    claims.push(("switching", "general", AreaKind::Mixed, true));
    let mut md = String::from(
        "\n## Shape checks (issue 7)\n\n| claim | success % | reach s | success difference, pp (95 % CI) | reach-time advantage, s (95 % CI) | holds |\n|---|---:|---:|---:|---:|:---:|\n",
    );
    for (a, b, area, strictly) in claims {
        let (Some(x), Some(y)) = (find(a, area), find(b, area)) else {
            continue;
        };
        let (d, half) = success_difference(&x, &y);
        let (faster, faster_half) = reach_advantage(&x, &y);
        let holds = if strictly {
            d - half > 0.0 || (d >= 0.0 && faster - faster_half > 0.0)
        } else {
            rank(&x) >= rank(&y)
        };
        // Worse beyond the noise: a lower success rate, or one not higher and a longer
        // reach time.
        let worse = d + half < 0.0 || (d - half <= 0.0 && faster + faster_half < 0.0);
        let verdict = match (holds, worse) {
            (true, _) => "yes",
            (false, false) => "within noise",
            (false, true) => "no",
        };
        let reach = if faster_half.is_finite() {
            format!("{faster:+.2} ± {faster_half:.2}")
        } else {
            "-".into()
        };
        md += &format!(
            "| {a} {} {b} on {} | {:.1} vs {:.1} | {} vs {} | {d:+.1} ± {half:.1} | {reach} | {} |\n",
            if strictly { "better than" } else { "≥" },
            area.name(),
            x.success_pct(),
            y.success_pct(),
            x.reach(),
            y.reach(),
            verdict
        );
    }
    md
}

/// Orders cells by success rate, then by shorter mean reach time.
fn rank(c: &Cell) -> f64 {
    c.success_pct() * 1e3 - c.mean_reach_s.min(999.0)
}

/// Success-rate difference `x − y` in percentage points and the half-width of its 95 % Wald
/// interval.
fn success_difference(x: &Cell, y: &Cell) -> (f64, f64) {
    let p = |c: &Cell| c.successes as f64 / c.episodes.max(1) as f64;
    let var = |c: &Cell| p(c) * (1.0 - p(c)) / c.episodes.max(1) as f64;
    (
        100.0 * (p(x) - p(y)),
        100.0 * 1.96 * (var(x) + var(y)).sqrt(),
    )
}

/// How much shorter `x`'s mean reach time is than `y`'s, seconds, and the half-width of its
/// 95 % interval (Welch, normal quantile); undecided (0 ± ∞) unless both have successes.
fn reach_advantage(x: &Cell, y: &Cell) -> (f64, f64) {
    if x.successes == 0 || y.successes == 0 {
        return (0.0, f64::INFINITY);
    }
    let var = |c: &Cell| c.std_reach_s.powi(2) / c.successes as f64;
    (
        y.mean_reach_s - x.mean_reach_s,
        1.96 * (var(x) + var(y)).sqrt(),
    )
}

/// The paper's Table 1 cell for `model` in `area`, if the paper has one.
fn paper_cell(model: &str, area: AreaKind) -> Option<PaperCell> {
    PAPER_TABLE_1
        .iter()
        .find(|(m, _)| *m == model)
        .and_then(|(_, a)| a.get(area.code() as usize).copied())
}

/// Pools evaluation parts: counts add, reach-time moments combine exactly.
fn merge(parts: &[Cell]) -> Cell {
    let episodes = parts.iter().map(|c| c.episodes).sum();
    let successes: u64 = parts.iter().map(|c| c.successes).sum();
    let n = successes.max(1) as f64;
    let mean = parts
        .iter()
        .map(|c| c.mean_reach_s * c.successes as f64)
        .sum::<f64>()
        / n;
    let second = parts
        .iter()
        .map(|c| (c.std_reach_s.powi(2) + c.mean_reach_s.powi(2)) * c.successes as f64)
        .sum::<f64>()
        / n;
    Cell {
        episodes,
        successes,
        mean_reach_s: mean,
        std_reach_s: (second - mean * mean).max(0.0).sqrt(),
    }
}

fn report(p: &Pipeline, cells: &[(String, AreaKind, Cell)]) -> anyhow::Result<String> {
    let mut md = String::from("# lavatube reproduce\n\n");
    md += "The paper's pipeline (SPEC S6-S8) regenerated by `lavatube reproduce`; the resolved \
           config is `config.toml` beside this report.\n\n## Table 1: success rate and reach time\n\n";
    let r = &p.base.reproduce;
    let trained = p.base.sim.terrain.roughness_scale;
    md += &format!(
        "Ground: `roughness-scale` {trained} for stages a-d, {} for the fine-tuning (e) and {} \
         for this evaluation (f).\n\n",
        r.finetune_roughness_scale.unwrap_or(trained),
        r.eval_roughness_scale.unwrap_or(trained)
    );
    md += "| model | area | ours: success % (episodes) | ours: reach s, mean (std) | paper: success % | paper: reach s |\n|---|---|---:|---:|---:|---:|\n";
    for (name, area, cell) in cells {
        let (ps, pr) = paper_cell(name, *area).map_or(("-".into(), "-".into()), |(s, m, sd)| {
            (format!("{s:.1}"), format!("{m:.2} ({sd:.2})"))
        });
        md += &format!(
            "| {name} | {} | {:.1} ({}) | {} | {ps} | {pr} |\n",
            area.name(),
            cell.success_pct(),
            cell.episodes,
            cell.reach()
        );
    }
    md += &shape_checks(cells);
    let analysis = p.stage_dir("d-analysis");
    let table3 = std::fs::read_to_string(analysis.join("results.md"))
        .with_context(|| format!("cannot read {}", analysis.join("results.md").display()))?;
    md += "\n## Table 3 and Figs. 5-8 (stage d)\n\n";
    // Its own headings one level down, its figure links relative to this report.
    let table3 = table3
        .replace("](", "](d-analysis/")
        .replace("\n## ", "\n### ");
    md += table3.strip_prefix("# ").map_or(&table3[..], |t| {
        t.split_once('\n').map_or(t, |(_, rest)| rest)
    });
    md += "\n## Learning curves\n\n";
    for (stage, slot) in [
        ("a-flat", PolicySlot::General),
        ("b-general", PolicySlot::General),
        ("e-specialists", PolicySlot::Flat),
        ("e-specialists", PolicySlot::Rough),
    ] {
        let png = learner_dir(&p.stage_dir(stage), slot).join("curves.png");
        if png.is_file() {
            let rel = png.strip_prefix(&p.out).unwrap_or(&png);
            md += &format!("![{stage} {}]({})\n\n", slot.name(), rel.display());
        }
    }
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episodes_and_reach_times_come_from_the_telemetry() {
        let dir = tempfile::tempdir().expect("tempdir");
        let csv = dir.path().join("t.csv");
        // env 0: success after 3 ticks, then a truncation after 2; env 1: success after 1.
        std::fs::write(
            &csv,
            "env,tick,terminated,truncated,success\n\
             0,0,false,false,false\n1,0,true,false,true\n\
             0,1,false,false,false\n0,2,true,false,true\n\
             0,3,false,false,false\n0,4,false,true,false\n",
        )
        .expect("write");
        let c = episodes_in(&csv, 0.1).expect("parse");
        assert_eq!((c.episodes, c.successes), (3, 2));
        assert!((c.mean_reach_s - 0.2).abs() < 1e-12 && (c.std_reach_s - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_confidence_interval_uses_students_t() {
        // sd 1, n 3: 4.303 / sqrt(3).
        let (m, h) = mean_ci(&[1.0, 2.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((h - 4.303 / 3f64.sqrt()).abs() < 1e-12);
        assert!(mean_ci(&[5.0]).1.is_nan());
    }

    #[test]
    fn merged_cells_equal_one_pooled_cell() {
        let a = Cell {
            episodes: 3,
            successes: 2,
            mean_reach_s: 1.0,
            std_reach_s: 0.5,
        };
        let b = Cell {
            episodes: 2,
            successes: 1,
            mean_reach_s: 4.0,
            std_reach_s: 0.0,
        };
        // Pooled reach times {0.5, 1.5, 4.0}: mean 2, variance (2.25 + 0.25 + 4) / 3.
        let m = merge(&[a, b]);
        assert_eq!((m.episodes, m.successes), (5, 3));
        assert!((m.mean_reach_s - 2.0).abs() < 1e-12);
        assert!((m.std_reach_s - (6.5f64 / 3.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn shape_checks_rank_by_success_then_reach_time() {
        let cell = |episodes, successes, mean_reach_s| Cell {
            episodes,
            successes,
            mean_reach_s,
            std_reach_s: 2.0,
        };
        let mut cells = Vec::new();
        for area in EVAL_AREAS {
            cells.push(("general".to_string(), area, cell(100, 90, 5.0)));
            cells.push(("FTM".to_string(), area, cell(100, 90, 4.0)));
            cells.push(("RTM".to_string(), area, cell(100, 95, 6.0)));
            cells.push(("switching".to_string(), area, cell(100, 95, 6.0)));
        }
        let md = shape_checks(&cells);
        let row = |claim| row_of(&md, claim);
        // Same success, faster: at least as good. Best single on flat is RTM (95 %).
        assert!(row("FTM ≥ general on flat").ends_with("| yes |"));
        assert!(row("switching ≥ RTM on flat").ends_with("| yes |"));
        // 95 % vs 90 % of 100 each: +5.0 pp ± 1.96·sqrt(.95·.05/100 + .9·.1/100) = ±7.3,
        // which holds 0; and 1 s slower, beyond ±1.96·sqrt(4/95 + 4/90) = ±0.58 s.
        assert!(
            row("switching better than general on mixed")
                .ends_with("| +5.0 ± 7.3 | -1.00 ± 0.58 | no |")
        );
        // 0.5 s slower with the same success: inside the noise.
        cells[11].2 = cell(100, 95, 6.5);
        assert!(
            row_of(&shape_checks(&cells), "switching ≥ RTM on mixed").ends_with("| within noise |")
        );
        cells[11].2 = cell(1000, 800, 6.0);
        assert!(row_of(&shape_checks(&cells), "switching ≥ RTM on mixed").ends_with("| no |"));
        // 0.2 pp lower success (inside ±1.2) but 0.3 s faster: not worse beyond the noise.
        cells[11].2 = cell(1000, 980, 5.7);
        cells[8].2 = cell(1000, 982, 6.0);
        assert!(
            row_of(&shape_checks(&cells), "switching ≥ general on mixed")
                .ends_with("| -0.2 ± 1.2 | +0.30 ± 0.18 | within noise |")
        );
        cells[11].2 = cell(1000, 999, 6.0);
        cells[8].2 = cell(1000, 900, 6.0);
        assert!(
            row_of(
                &shape_checks(&cells),
                "switching better than general on mixed"
            )
            .ends_with("| yes |")
        );
    }

    fn row_of(md: &str, claim: &str) -> String {
        md.lines()
            .find(|l| l.starts_with(&format!("| {claim} |")))
            .unwrap_or_else(|| panic!("no row {claim} in\n{md}"))
            .to_string()
    }
}
