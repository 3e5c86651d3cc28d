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
//!    `e-select` (with `reproduce.specialist-candidates`): each specialist is the best on its
//!    own terrain's validation courses of the general model and stage e's milestones;
//! f. `f-eval`: success rate and reach time of general, FTM and RTM in each area (Table 1),
//!    and of switching between FTM and RTM on stage d's terrain mixture, every model on the
//!    same seeded courses (`EpisodeStart::Course`);
//! g. `report.md`: every table beside the paper's numbers, figures, learning curves, and the
//!    issue's claims checked leg by leg on the legs both models drove.

use super::UserError;
use super::run::{TELEMETRY_CSV, execute, learner_dir};
use crate::supervise;
use anyhow::Context;
use common::Config;
use common::config::{Acting, AreaKind, EpisodeStart, PolicySlot};
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

/// Validation courses' seeds start this far from the run's, so stage e's choice of
/// specialist never drives stage f's courses.
const VALIDATION_SEEDS: u64 = 1 << 20;

/// The courses an evaluation drives: the stage that drives them (for progress lines), the
/// first seed (a cell short of its episodes drives the next), the episodes a cell needs, and
/// the ticks per env of one run.
#[derive(Debug, Clone, Copy)]
struct Courses {
    stage: &'static str,
    seed: u64,
    episodes: u64,
    ticks: u64,
}

/// Stage f's guess at the ticks an evaluation episode lasts, to size its runs: trained
/// models reach the target in about 40 (3.5-4 s at 0.1 s per tick).
const EPISODE_TICKS_GUESS: u64 = 50;

/// SPEC S7's Table 3: window, accuracy %.
const PAPER_TABLE_3: [(u64, f64); 4] = [(10, 61.13), (20, 70.73), (40, 85.87), (70, 98.79)];

/// Each leg an evaluation drove, by run (part), env and leg: its length in decision steps
/// when the robot reached the target, `None` when the leg failed. Stage f drives every model
/// on the same seeded courses (`EpisodeStart::Course`), so two models' legs pair up by index.
type Legs = Vec<Vec<Vec<Option<u32>>>>;

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
    /// Success count and reach-time moments of every leg in `legs`.
    fn of(legs: &Legs, decision_dt: f64) -> Self {
        let all: Vec<Option<u32>> = legs.iter().flatten().flatten().copied().collect();
        let reach: Vec<f64> = all
            .iter()
            .flatten()
            .map(|&t| t as f64 * decision_dt)
            .collect();
        let n = reach.len().max(1) as f64;
        let mean = reach.iter().sum::<f64>() / n;
        let var = reach.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n;
        Self {
            episodes: all.len() as u64,
            successes: reach.len() as u64,
            mean_reach_s: mean,
            std_reach_s: var.sqrt(),
        }
    }

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

/// A model's evaluation in an area: every leg it drove.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Evaluated {
    model: String,
    area: AreaKind,
    legs: Legs,
}

/// The legs each env ended in a telemetry CSV (`sim-proc --telemetry`), in order: a leg's
/// length runs from the env's first row after the previous ending to the row that ends it.
/// Legs still running at the end are left out.
fn legs_in(path: &Path) -> anyhow::Result<Vec<Vec<Option<u32>>>> {
    let mut reader =
        csv::Reader::from_path(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut legs: Vec<Vec<Option<u32>>> = Vec::new();
    let mut length: Vec<u32> = Vec::new();
    for (i, row) in reader.deserialize::<common::TelemetryRow>().enumerate() {
        let row = row.with_context(|| format!("{}: row {}", path.display(), i + 1))?;
        let (e, leg) = (row.env as usize, row.episode as usize);
        if e >= legs.len() {
            legs.resize(e + 1, Vec::new());
            length.resize(e + 1, 0);
        }
        // A sim restarted inside a run starts its courses again: its legs would not pair.
        anyhow::ensure!(
            leg == legs[e].len(),
            "{}: env {e} is on leg {leg} after ending {} (the sim restarted?)",
            path.display(),
            legs[e].len()
        );
        length[e] += 1;
        if row.terminated || row.truncated {
            legs[e].push(row.success.then_some(length[e]));
            length[e] = 0;
        }
    }
    Ok(legs)
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

    /// Stage `name`'s checkpoints of the learner for `slot`, oldest first, each with the
    /// update it was taken after.
    fn checkpoints(&self, name: &str, slot: PolicySlot) -> anyhow::Result<Vec<(u64, PathBuf)>> {
        let dir = learner_dir(&self.stage_dir(name), slot).join("checkpoints");
        let mut files: Vec<(u64, PathBuf)> = std::fs::read_dir(&dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter_map(|p| {
                let update = p
                    .file_name()?
                    .to_str()?
                    .strip_prefix("checkpoint-")?
                    .strip_suffix(".ckpt")?
                    .parse()
                    .ok()?;
                Some((update, p))
            })
            .collect();
        files.sort();
        anyhow::ensure!(!files.is_empty(), "no checkpoint in {}", dir.display());
        Ok(files)
    }

    /// The newest checkpoint of stage `name`'s learner for `slot`.
    fn checkpoint(&self, name: &str, slot: PolicySlot) -> anyhow::Result<PathBuf> {
        let newest = self.checkpoints(name, slot)?.pop();
        newest
            .map(|(_, p)| p)
            .with_context(|| format!("stage {name} left no checkpoint"))
    }

    /// Stage e's `ppo.milestone-every`: `reproduce.specialist-candidates` milestones spread
    /// evenly over each specialist's updates (one per rollout), the last one at the end.
    fn milestone_every(&self) -> usize {
        let (r, ppo) = (&self.base.reproduce, &self.base.ppo);
        let updates = (r.finetune_steps / ppo.rollout_transitions as u64).max(1) as usize;
        updates
            .div_ceil(r.specialist_candidates.max(1))
            .next_multiple_of(ppo.checkpoint_every)
    }

    /// Early stopping for the specialist `model`, fine-tuned in stage e by the learner of
    /// `slot`: the general model (`general`, no fine-tuning), stage e's milestones and its
    /// last checkpoint each drive validation courses in `area`; the [`best`] wins.
    fn select(
        &self,
        model: &str,
        slot: PolicySlot,
        area: AreaKind,
        general: &Path,
    ) -> anyhow::Result<Selection> {
        let dir = self.stage_dir("e-select");
        let every = self.milestone_every() as u64;
        let all = self.checkpoints("e-specialists", slot)?;
        let last = all.len() - 1;
        let mut tried = vec![(GENERAL.to_string(), general.to_path_buf())];
        tried.extend(
            all.into_iter()
                .enumerate()
                .filter(|(i, (update, _))| *i == last || update.is_multiple_of(every))
                .map(|(_, (update, ckpt))| (format!("update {update}"), ckpt)),
        );
        let courses = self.validation_courses();
        let mut candidates = Vec::new();
        let mut legs = Vec::new();
        for (k, (label, checkpoint)) in tried.into_iter().enumerate() {
            let weights = dir.join(format!("{}-{k}.policy", model.to_lowercase()));
            self.export(&checkpoint, &weights)?;
            let name = format!("{model}-{}", label.replace(' ', "-"));
            let driven = self.evaluate_policy(&name, &weights, area, courses, &dir)?;
            candidates.push(Candidate {
                label,
                checkpoint,
                cell: Some(Cell::of(&driven.legs, self.base.sim.decision_dt())),
            });
            legs.push(driven.legs);
        }
        let chosen = best(&legs, self.base.reproduce.margin_pp);
        self.say(&format!(
            "e-select: {model} is {} ({} candidates)",
            candidates[chosen].label,
            candidates.len()
        ));
        Ok(Selection {
            model: model.into(),
            area,
            candidates,
            chosen,
        })
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

    /// Evaluates `model` in `area` on `courses`: runs `run_part` (the config, the part's
    /// name; returns its telemetry CSV) with seeds `courses.seed`, +1, … until the cell has
    /// its episodes. Every model runs the same seeds on the same courses, so their legs pair up.
    fn evaluate(
        &self,
        model: &str,
        area: AreaKind,
        courses: Courses,
        mut run_part: impl FnMut(&Config, &str) -> anyhow::Result<PathBuf>,
    ) -> anyhow::Result<Evaluated> {
        let mut cfg = self.eval_in(area);
        cfg.run.seed = courses.seed;
        let mut legs = Legs::new();
        let dt = cfg.sim.decision_dt();
        while Cell::of(&legs, dt).episodes < courses.episodes {
            let name = format!("{}-{}-{}", model.to_lowercase(), area.name(), legs.len());
            let csv = run_part(&cfg, &name)?;
            let part = legs_in(&csv)?;
            anyhow::ensure!(
                part.iter().any(|env| !env.is_empty()),
                "{} holds no finished episode",
                csv.display()
            );
            legs.push(part);
            cfg.run.seed = cfg.run.seed.wrapping_add(1);
        }
        let cell = Cell::of(&legs, dt);
        self.say(&format!(
            "{}: {model} on {} ground: {:.1}% of {} episodes, reach s {}",
            courses.stage,
            area.name(),
            cell.success_pct(),
            cell.episodes,
            cell.reach()
        ));
        Ok(Evaluated {
            model: model.into(),
            area,
            legs,
        })
    }

    /// `weights` alone (`sim-proc`) on `courses` in `area`, its telemetry in `dir`.
    fn evaluate_policy(
        &self,
        model: &str,
        weights: &Path,
        area: AreaKind,
        courses: Courses,
        dir: &Path,
    ) -> anyhow::Result<Evaluated> {
        self.evaluate(model, area, courses, |cfg, part| {
            let csv = dir.join(format!("{part}.csv"));
            self.drive(cfg, weights, courses.ticks, &csv)?;
            Ok(csv)
        })
    }

    /// SPEC S8's switching policy in `area`: FTM and RTM served frozen, each env acting with
    /// the one its live terrain estimate points to (mean actions), through the full runtime
    /// with the estimator.
    fn switching(
        &self,
        area: AreaKind,
        frozen: &std::collections::BTreeMap<PolicySlot, PathBuf>,
        eval: &Path,
    ) -> anyhow::Result<Evaluated> {
        let courses = self.test_courses();
        let steps = courses.ticks * self.base.reproduce.eval_envs as u64;
        self.evaluate("switching", area, courses, |base, name| {
            let mut cfg = base.clone();
            cfg.run.learners.clear();
            cfg.run.frozen = frozen.clone();
            cfg.run.mode = common::config::LearnMode::Async;
            cfg.run.out_dir = eval.to_path_buf();
            cfg.run.telemetry_csv = true;
            cfg.run.total_steps = steps;
            cfg.sim.acting = Acting::Switch;
            cfg.sim.mean_actions = true;
            // SPEC S7-S8: the estimator classifies with stage d's mixture, fitted on both
            // terrains, and is not refitted: a fit on one area's windows alone would split
            // that terrain into two classes and hand half of it to the other specialist.
            cfg.estimator.model = Some(self.stage_dir("d-analysis").join("results.json"));
            cfg.estimator.refit_every = 0;
            cfg.validate()?;
            if !execute(&cfg, name, &self.run_id(name), self.quiet)? {
                anyhow::bail!("interrupted during {name}; run again to resume");
            }
            Ok(eval.join(name).join(TELEMETRY_CSV))
        })
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
    /// evaluation's ground, each driving a seeded course (the same legs for every model).
    fn eval_in(&self, area: AreaKind) -> Config {
        let r = &self.base.reproduce;
        let mut c = self.base.clone();
        c.sim.only_in(area, r.eval_envs);
        c.sim.task.episodes = EpisodeStart::Course;
        if let Some(scale) = r.eval_roughness_scale {
            c.sim.terrain.roughness_scale = scale;
        }
        c
    }

    /// Courses of `episodes` per cell from seed `seed` on. Ticks per env of one run: enough
    /// for the episodes at `EPISODE_TICKS_GUESS` ticks each, and for every env to end one
    /// episode however long it lasts. A cell short of its episodes runs again with the next seed.
    fn courses(&self, stage: &'static str, seed: u64, episodes: u64) -> Courses {
        let envs = self.base.reproduce.eval_envs as u64;
        Courses {
            stage,
            seed,
            episodes,
            ticks: (episodes.div_ceil(envs) * EPISODE_TICKS_GUESS)
                .max(self.base.sim.task.longest_episode_ticks() + 1),
        }
    }

    /// Stage f's courses, from the run's seed on.
    fn test_courses(&self) -> Courses {
        let r = &self.base.reproduce;
        self.courses("f-eval", self.base.run.seed, r.eval_episodes)
    }

    /// Stage e's validation courses, `VALIDATION_SEEDS` away from stage f's.
    fn validation_courses(&self) -> Courses {
        let r = &self.base.reproduce;
        let seed = self.base.run.seed.wrapping_add(VALIDATION_SEEDS);
        self.courses("e-select", seed, r.validation_episodes)
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
        let n = r.collect_envs.unwrap_or(r.envs_per_area);
        p.drive(&p.envs(n, n), &general, r.collect_steps, &traces)?;
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
    if r.specialist_candidates > 0 {
        e.ppo.milestone_every = p.milestone_every();
    }
    p.train("e-specialists", e)?;
    let selections = specialists(p)?;
    let models = [
        ("general", general),
        ("FTM", policies.join("ftm.policy")),
        ("RTM", policies.join("rtm.policy")),
    ];
    for ((_, weights), s) in models[1..].iter().zip(&selections) {
        p.export(s.checkpoint(), weights)?;
    }

    let eval = p.stage_dir("f-eval");
    let cells_path = eval.join("cells.json");
    let cells: Vec<Evaluated> = if p.done("f-eval") {
        serde_json::from_str(&std::fs::read_to_string(&cells_path)?).with_context(|| {
            format!(
                "{} is not stage f's legs (an older lavatube's?): remove {} to evaluate again",
                cells_path.display(),
                eval.display()
            )
        })?
    } else {
        std::fs::create_dir_all(p.fresh("f-eval")?)?;
        let mut cells = Vec::new();
        for (name, weights) in &models {
            for area in EVAL_AREAS {
                cells.push(p.evaluate_policy(name, weights, area, p.test_courses(), &eval)?);
            }
        }
        let frozen = [PolicySlot::Flat, PolicySlot::Rough]
            .into_iter()
            .zip(selections.iter().map(|s| s.checkpoint().to_path_buf()))
            .collect();
        for area in EVAL_AREAS {
            cells.push(p.switching(area, &frozen, &eval)?);
        }
        std::fs::write(&cells_path, serde_json::to_string(&cells)?)?;
        p.finish("f-eval", serde_json::json!({ "cells": cells.len() }))?;
        cells
    };

    let report = report(p, &cells, &selections)?;
    let path = out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    println!("report: {}", path.display());
    Ok(cells)
}

/// A specialist's candidates on its terrain's validation courses (stage e), and the one
/// chosen. Without candidates (`reproduce.specialist-candidates` = 0, the paper's) the only
/// one is the fine-tuning's last checkpoint, not validated.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Selection {
    model: String,
    area: AreaKind,
    candidates: Vec<Candidate>,
    chosen: usize,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Candidate {
    /// "general" (no fine-tuning) or "update N" of the fine-tuning.
    label: String,
    checkpoint: PathBuf,
    /// On the validation courses; `None` when not validated.
    cell: Option<Cell>,
}

impl Selection {
    fn checkpoint(&self) -> &Path {
        &self.candidates[self.chosen].checkpoint
    }
}

/// Where stage `e-select` keeps its [`Selection`]s.
const SELECTION_JSON: &str = "selection.json";

/// The candidate that is the general model, before any fine-tuning.
const GENERAL: &str = "general";

/// The heading of the specialists' choice, in a run's report and in the seeds report.
const SELECTION_HEADING: &str = "## Specialists chosen on validation courses (stage e)";

/// Stage `e-select`'s choice, if it finished.
fn chosen_before(p: &Pipeline) -> anyhow::Result<Option<Vec<Selection>>> {
    if !p.done("e-select") {
        return Ok(None);
    }
    let path = p.stage_dir("e-select").join(SELECTION_JSON);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).map(Some).with_context(|| {
        format!(
            "{} is not stage e's selection: remove its directory to select again",
            path.display()
        )
    })
}

/// FTM and RTM (SPEC S8): stage e's last checkpoints, or with `specialist-candidates` the
/// ones stage `e-select` validates best ([`Pipeline::select`]), chosen once and kept.
fn specialists(p: &Pipeline) -> anyhow::Result<Vec<Selection>> {
    let roles = [
        ("FTM", PolicySlot::Flat, AreaKind::Flat),
        ("RTM", PolicySlot::Rough, AreaKind::Rough),
    ];
    if p.base.reproduce.specialist_candidates == 0 {
        return roles
            .into_iter()
            .map(|(model, slot, area)| {
                let checkpoint = p.checkpoint("e-specialists", slot)?;
                Ok(Selection {
                    model: model.into(),
                    area,
                    candidates: vec![Candidate {
                        label: "last checkpoint".into(),
                        checkpoint,
                        cell: None,
                    }],
                    chosen: 0,
                })
            })
            .collect();
    }
    if let Some(chosen) = chosen_before(p)? {
        return Ok(chosen);
    }
    let path = p.stage_dir("e-select").join(SELECTION_JSON);
    std::fs::create_dir_all(p.fresh("e-select")?)?;
    p.say("e-select: each specialist's candidates on validation courses of its terrain");
    let general = p.checkpoint("b-general", PolicySlot::General)?;
    let chosen = roles
        .into_iter()
        .map(|(model, slot, area)| p.select(model, slot, area, &general))
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::write(&path, serde_json::to_string_pretty(&chosen)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    p.finish("e-select", serde_json::json!({ "selection": path }))?;
    Ok(chosen)
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
    for (i, Evaluated { model, area, .. }) in first.iter().enumerate() {
        let cells: Vec<Cell> = runs
            .iter()
            .filter_map(|(p, c)| {
                c.get(i)
                    .map(|c| Cell::of(&c.legs, p.base.sim.decision_dt()))
            })
            .collect();
        let success: Vec<f64> = cells.iter().map(|c| c.success_pct()).collect();
        let reach: Vec<f64> = cells
            .iter()
            .filter(|c| c.successes > 0)
            .map(|c| c.mean_reach_s)
            .collect();
        let paper = paper_cell(model, *area).map_or("-".into(), |(s, _, _)| format!("{s:.1}"));
        md += &format!(
            "| {model} | {} | {} | {} | {paper} |\n",
            area.name(),
            pm(&success, 1),
            if reach.is_empty() {
                "-".into()
            } else {
                pm(&reach, 2)
            }
        );
    }
    md += "\n## Shape checks (issue 7)\n\nPer seed on the legs both models drove (see each seed's report); the differences are means over seeds ± 95 % CI.\n\n| claim | success difference, pp | reach-time advantage, s | holds, per seed |\n|---|---:|---:|---|\n";
    let per_seed: Vec<(u64, Vec<Check>)> = runs
        .iter()
        .map(|(p, cells)| {
            let r = &p.base.reproduce;
            (
                p.base.run.seed,
                checks(cells, p.base.sim.decision_dt(), (r.margin_pp, r.margin_s)),
            )
        })
        .collect();
    for key in per_seed
        .first()
        .map(|(_, c)| c)
        .into_iter()
        .flatten()
        .map(|c| &c.key)
    {
        let of_key: Vec<(u64, &Check)> = per_seed
            .iter()
            .filter_map(|(seed, cs)| cs.iter().find(|c| &c.key == key).map(|c| (*seed, c)))
            .collect();
        let d: Vec<f64> = of_key.iter().map(|(_, c)| c.paired.difference.0).collect();
        let faster: Vec<f64> = of_key
            .iter()
            .filter(|(_, c)| c.paired.reached_by_both > 0)
            .map(|(_, c)| c.paired.faster.0)
            .collect();
        let verdicts: Vec<String> = of_key
            .iter()
            .map(|(seed, c)| {
                let versus = if c.claim == *key {
                    String::new()
                } else {
                    format!(" ({})", c.claim)
                };
                format!("seed {seed}: {}{versus}", c.verdict)
            })
            .collect();
        md += &format!(
            "| {key} | {} | {} | {} |\n",
            pm(&d, 1),
            if faster.is_empty() {
                "-".into()
            } else {
                pm(&faster, 2)
            },
            verdicts.join("; ")
        );
    }
    let mut chosen = String::new();
    // None without `specialist-candidates`, whatever an earlier config left in `e-select`.
    for (p, _) in runs
        .iter()
        .filter(|(p, _)| p.base.reproduce.specialist_candidates > 0)
    {
        for s in chosen_before(p)?.into_iter().flatten() {
            chosen += &format!(
                "| {} | {} | {} |\n",
                p.base.run.seed, s.model, s.candidates[s.chosen].label
            );
        }
    }
    if !chosen.is_empty() {
        md += &format!(
            "\n{SELECTION_HEADING}\n\n| seed | model | chosen |\n|---:|---|---|\n{chosen}"
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

/// Issue 7's claims about Table 1, each checked leg by leg: both models drove the same seeded
/// courses, so each claim compares them on the legs both drove (paired). A model "at least as
/// good" reached the target on more of those legs, or on as many and sooner on average over
/// the legs both reached. Each row gives the success-rate difference and the reach-time
/// advantage with their 95 % intervals over the paired legs. A model falls short when it is
/// worse by more than a margin (`reproduce.margin-pp`, `margin-s`) beyond the noise: a success
/// rate lower, or one not higher and a reach time longer. A claim that fails on the point
/// estimates reads "no" only when the model falls short, else "within margin". "Better than"
/// needs one measure better beyond the noise and the other not short: a success rate higher
/// beyond the noise with the reach time no longer than the margin beyond it, or a reach time
/// shorter beyond the noise with the success rate no lower than the margin beyond it; else it
/// reads "no" when the model falls short and "not shown" when it does not.
fn shape_checks(cells: &[Evaluated], decision_dt: f64, margins: (f64, f64)) -> String {
    let (margin_pp, margin_s) = margins;
    let mut md = format!(
        "\n## Shape checks (issue 7)\n\nEach claim compares the two models on the legs both drove (same seed, env and leg of the evaluation course). \"At least as good\" reads \"no\" only when the first model falls short by more than {margin_pp} pp of success or {margin_s} s of reach time beyond the noise (`reproduce.margin-pp`, `margin-s`).\n\n| claim | paired legs | success % | reach s, legs both reached | success difference, pp (95 % CI) | reach-time advantage, s (95 % CI) | holds |\n|---|---:|---:|---:|---:|---:|:---:|\n",
    );
    for Check {
        claim,
        paired: c,
        verdict,
        ..
    } in checks(cells, decision_dt, margins)
    {
        let ((d, half), (faster, faster_half)) = (c.difference, c.faster);
        let (reach, advantage) = if c.reached_by_both > 0 {
            (
                format!("{:.2} vs {:.2}", c.reach[0], c.reach[1]),
                format!("{faster:+.2} ± {faster_half:.2}"),
            )
        } else {
            ("-".into(), "-".into())
        };
        md += &format!(
            "| {claim} | {} | {:.1} vs {:.1} | {reach} | {d:+.1} ± {half:.1} | {advantage} | {verdict} |\n",
            c.legs, c.success[0], c.success[1],
        );
    }
    md
}

/// One of issue 7's claims, checked on one seed's cells.
struct Check {
    /// E.g. "switching ≥ RTM on rough".
    claim: String,
    /// The claim with the best single model unnamed ("switching ≥ the best single model on
    /// rough"), which lines seeds up when their best single models differ.
    key: String,
    paired: Paired,
    verdict: &'static str,
}

/// Issue 7's claims on `cells` (see [`shape_checks`]).
fn checks(cells: &[Evaluated], decision_dt: f64, margins: (f64, f64)) -> Vec<Check> {
    let find =
        |model: &str, area: AreaKind| cells.iter().find(|c| c.model == model && c.area == area);
    let best_single = |area: AreaKind| {
        ["general", "FTM", "RTM"]
            .into_iter()
            .filter_map(|m| find(m, area).map(|c| (m, Cell::of(&c.legs, decision_dt))))
            .max_by(|(_, a), (_, b)| rank(a).total_cmp(&rank(b)))
    };
    let mut claims = vec![
        ("FTM", "general", AreaKind::Flat, false, false),
        ("RTM", "general", AreaKind::Rough, false, false),
    ];
    for area in EVAL_AREAS {
        if let Some((m, _)) = best_single(area) {
            claims.push(("switching", m, area, false, true));
        }
    }
    claims.push(("switching", "general", AreaKind::Mixed, true, false));
    let (margin_pp, margin_s) = margins;
    let mut out = Vec::new();
    for (a, b, area, strictly, best) in claims {
        let (Some(x), Some(y)) = (find(a, area), find(b, area)) else {
            continue;
        };
        let c = Paired::of(&x.legs, &y.legs, decision_dt);
        let ((d, half), (faster, faster_half)) = (c.difference, c.faster);
        // Short by more than the margins beyond the noise, on success and on reach time.
        let (short_success, short_reach) =
            (d + half < -margin_pp, faster + faster_half < -margin_s);
        let holds = if strictly {
            (d - half > 0.0 && !short_reach) || (faster - faster_half > 0.0 && !short_success)
        } else {
            d > 0.0 || (d == 0.0 && faster >= 0.0)
        };
        let short = short_success || (d - half <= 0.0 && short_reach);
        let verdict = match (holds, short, strictly) {
            (true, _, _) => "yes",
            (false, true, _) => "no",
            (false, false, false) => "within margin",
            (false, false, true) => "not shown",
        };
        let relation = if strictly { "better than" } else { "≥" };
        let claim = |b: &str| format!("{a} {relation} {b} on {}", area.name());
        out.push(Check {
            claim: claim(b),
            key: if best {
                claim("the best single model")
            } else {
                claim(b)
            },
            paired: c,
            verdict,
        });
    }
    out
}

/// The legs every one of `legs` drove (same part, env and leg index): per leg, each one's
/// outcome, in the order of `legs`.
fn common_legs(legs: &[&Legs]) -> Vec<Vec<Option<u32>>> {
    let shortest = |len: &dyn Fn(&Legs) -> usize| legs.iter().map(|l| len(l)).min().unwrap_or(0);
    let mut out = Vec::new();
    for part in 0..shortest(&|l| l.len()) {
        for env in 0..shortest(&|l| l[part].len()) {
            for leg in 0..shortest(&|l| l[part][env].len()) {
                out.push(legs.iter().map(|l| l[part][env][leg]).collect());
            }
        }
    }
    out
}

/// The best of several models' `legs` on the same courses: among those whose success rate
/// on the legs all drove is within `margin_pp` of the highest (closer is noise at validation
/// sizes), the one with the shortest mean reach time on the legs all of those reached; the
/// first of equals (the least fine-tuned candidate, in [`Pipeline::select`]'s order).
fn best(legs: &[Legs], margin_pp: f64) -> usize {
    let all: Vec<&Legs> = legs.iter().collect();
    let driven = common_legs(&all);
    let success: Vec<f64> = (0..legs.len())
        .map(|k| 100.0 * driven.iter().filter(|l| l[k].is_some()).count() as f64)
        .map(|s| s / driven.len().max(1) as f64)
        .collect();
    let top = success.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let near: Vec<usize> = (0..legs.len())
        .filter(|&k| success[k] >= top - margin_pp)
        .collect();
    let reached: Vec<Vec<u32>> = common_legs(&near.iter().map(|&k| &legs[k]).collect::<Vec<_>>())
        .into_iter()
        .filter_map(|leg| leg.into_iter().collect())
        .collect();
    let reach = |i: usize| reached.iter().map(|r| u64::from(r[i])).sum::<u64>();
    (0..near.len())
        .reduce(|b, i| if reach(i) < reach(b) { i } else { b })
        .map_or(0, |i| near[i])
}

/// Orders cells by success rate, then by shorter mean reach time.
fn rank(c: &Cell) -> f64 {
    c.success_pct() * 1e3 - c.mean_reach_s.min(999.0)
}

/// Two models `x` and `y` compared on the legs both drove (same part, env and leg index).
#[derive(Debug)]
struct Paired {
    legs: usize,
    /// Success % of `x` and of `y` on those legs.
    success: [f64; 2],
    /// Legs both reached, and `x`'s and `y`'s mean reach time on them, seconds.
    reached_by_both: usize,
    reach: [f64; 2],
    /// `x`'s success rate minus `y`'s, percentage points, and the half-width of its 95 %
    /// interval (Student's t over the per-leg differences).
    difference: (f64, f64),
    /// How much sooner `x` reached the target than `y` on the legs both reached, seconds,
    /// and the half-width of its 95 % interval.
    faster: (f64, f64),
}

impl Paired {
    fn of(x: &Legs, y: &Legs, decision_dt: f64) -> Self {
        let pairs: Vec<(Option<u32>, Option<u32>)> = common_legs(&[x, y])
            .into_iter()
            .map(|l| (l[0], l[1]))
            .collect();
        let pct = |o: Option<u32>| if o.is_some() { 100.0 } else { 0.0 };
        let differences: Vec<f64> = pairs.iter().map(|&(a, b)| pct(a) - pct(b)).collect();
        let both: Vec<[f64; 2]> = pairs
            .iter()
            .filter_map(|&(a, b)| Some([a? as f64 * decision_dt, b? as f64 * decision_dt]))
            .collect();
        let sooner: Vec<f64> = both.iter().map(|[a, b]| b - a).collect();
        let mean = |xs: Vec<f64>| mean_ci(&xs).0;
        Self {
            legs: pairs.len(),
            success: [
                mean(pairs.iter().map(|p| pct(p.0)).collect()),
                mean(pairs.iter().map(|p| pct(p.1)).collect()),
            ],
            reached_by_both: both.len(),
            reach: [
                mean(both.iter().map(|b| b[0]).collect()),
                mean(both.iter().map(|b| b[1]).collect()),
            ],
            difference: mean_ci(&differences),
            faster: mean_ci(&sooner),
        }
    }
}

/// Stage e's choice of specialists, when it validated candidates (`specialist-candidates`).
fn selection_table(selections: &[Selection], episodes: u64) -> String {
    if selections.iter().all(|s| s.candidates.len() < 2) {
        return String::new();
    }
    let mut md = format!(
        "\n{SELECTION_HEADING}\n\nEach specialist is the candidate that did best on its own terrain over validation courses (about {episodes} episodes each, seeds apart from the evaluation's): the general model it was fine-tuned from, or a checkpoint of its fine-tuning (`reproduce.specialist-candidates`). Best = the shortest reach time among those within `margin-pp` of the highest success rate, each measured on the legs all of them drove or reached (the table shows each candidate's own legs).\n\n| model | area | candidate | success % (episodes) | reach s, mean (std) | chosen |\n|---|---|---|---:|---:|:---:|\n"
    );
    for s in selections {
        for (k, c) in s.candidates.iter().enumerate() {
            let (success, reach) = c.cell.map_or(("-".into(), "-".into()), |cell| {
                (
                    format!("{:.1} ({})", cell.success_pct(), cell.episodes),
                    cell.reach(),
                )
            });
            md += &format!(
                "| {} | {} | {} | {success} | {reach} | {} |\n",
                s.model,
                s.area.name(),
                c.label,
                if k == s.chosen { "**yes**" } else { "" }
            );
        }
    }
    md
}

/// The paper's Table 1 cell for `model` in `area`, if the paper has one.
fn paper_cell(model: &str, area: AreaKind) -> Option<PaperCell> {
    PAPER_TABLE_1
        .iter()
        .find(|(m, _)| *m == model)
        .and_then(|(_, a)| a.get(area.code() as usize).copied())
}

fn report(p: &Pipeline, cells: &[Evaluated], selections: &[Selection]) -> anyhow::Result<String> {
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
    for Evaluated { model, area, legs } in cells {
        let cell = Cell::of(legs, p.base.sim.decision_dt());
        let (ps, pr) = paper_cell(model, *area).map_or(("-".into(), "-".into()), |(s, m, sd)| {
            (format!("{s:.1}"), format!("{m:.2} ({sd:.2})"))
        });
        md += &format!(
            "| {model} | {} | {:.1} ({}) | {} | {ps} | {pr} |\n",
            area.name(),
            cell.success_pct(),
            cell.episodes,
            cell.reach()
        );
    }
    for s in selections {
        if s.candidates[s.chosen].label == GENERAL {
            md += &format!(
                "\n{} is the general model: no checkpoint of its fine-tuning drove {} ground better on the validation courses (stage e, below).\n",
                s.model,
                s.area.name()
            );
        }
    }
    md += &shape_checks(cells, p.base.sim.decision_dt(), (r.margin_pp, r.margin_s));
    md += &selection_table(selections, r.validation_episodes);
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

    /// Writes telemetry rows `(env, episode, ending)` as `sim-proc --telemetry` does; the
    /// ending is `Some(success)` on a leg's last row.
    fn write_telemetry(path: &Path, rows: &[(u32, u64, Option<bool>)]) {
        let mut w = csv::Writer::from_path(path).expect("csv");
        for (tick, &(env, episode, ending)) in rows.iter().enumerate() {
            w.serialize(common::TelemetryRow {
                env,
                tick: tick as u64,
                episode,
                terminated: ending == Some(true),
                truncated: ending == Some(false),
                success: ending == Some(true),
                ..Default::default()
            })
            .expect("row");
        }
        w.flush().expect("flush");
    }

    #[test]
    fn legs_and_reach_times_come_from_the_telemetry() {
        let dir = tempfile::tempdir().expect("tempdir");
        let csv = dir.path().join("t.csv");
        // env 0: success after 2 ticks, then a truncation after 2, then one leg unfinished;
        // env 1: success after 1.
        write_telemetry(
            &csv,
            &[
                (0, 0, None),
                (1, 0, Some(true)),
                (0, 0, Some(true)),
                (0, 1, None),
                (0, 1, Some(false)),
                (0, 2, None),
            ],
        );
        let legs = legs_in(&csv).expect("parse");
        assert_eq!(legs, vec![vec![Some(2), None], vec![Some(1)]]);
        // Reach times {0.2, 0.1} s of 3 legs.
        let c = Cell::of(&vec![legs], 0.1);
        assert_eq!((c.episodes, c.successes), (3, 2));
        assert!((c.mean_reach_s - 0.15).abs() < 1e-12 && (c.std_reach_s - 0.05).abs() < 1e-12);
        // A sim that restarted starts its legs again: those rows cannot pair.
        write_telemetry(&csv, &[(0, 0, Some(true)), (0, 0, None)]);
        let e = legs_in(&csv).expect_err("restart");
        assert!(
            e.to_string().contains("env 0 is on leg 0 after ending 1"),
            "{e}"
        );
        // A file of another layout is refused, naming the row.
        std::fs::write(&csv, "env,episode\n0,x\n").expect("write");
        let e = format!("{:#}", legs_in(&csv).expect_err("layout"));
        assert!(e.contains("t.csv: row 1"), "{e}");
    }

    #[test]
    fn the_best_candidate_succeeds_within_the_margin_then_reaches_soonest() {
        // One part, one env, ten legs; `None` failed.
        let legs = |l: &[Option<u32>]| -> Legs { vec![vec![l.to_vec()]] };
        let all = |t: u32| vec![Some(t); 10];
        let mut nine = all(30);
        nine[9] = None;
        // 100 % at 40 steps against 90 % at 30: 10 pp apart, success wins.
        assert_eq!(best(&[legs(&nine), legs(&all(40))], 1.0), 1);
        // Within a 10 pp margin the sooner wins, timed on the legs both reached (the failed
        // leg is left out of both: a 99-step leg there does not count against the first).
        let mut slow_last = all(30);
        slow_last[9] = Some(99);
        assert_eq!(best(&[legs(&slow_last), legs(&nine)], 10.0), 0);
        assert_eq!(best(&[legs(&all(31)), legs(&nine)], 10.0), 1);
        // Equals keep the first (the general model before any fine-tuning).
        assert_eq!(best(&[legs(&all(30)), legs(&all(30))], 1.0), 0);
        // Legs only one model drove (it drove more) do not count.
        let mut longer = all(30);
        longer.extend([Some(1); 5]);
        assert_eq!(best(&[legs(&all(30)), legs(&longer)], 1.0), 0);
        // No candidate reached a target: the first.
        assert_eq!(best(&[legs(&[None; 4]), legs(&[None; 4])], 1.0), 0);
    }

    #[test]
    fn milestones_spread_over_the_fine_tuning() {
        let mut base = Config::default();
        base.reproduce.finetune_steps = 2_000_000;
        base.reproduce.specialist_candidates = 4;
        let every = |base: &Config| {
            Pipeline {
                base: base.clone(),
                out: PathBuf::new(),
                quiet: true,
            }
            .milestone_every()
        };
        // 976 updates of 2,048 transitions: milestones at 244, 488, 732 and 976.
        assert_eq!(every(&base), 244);
        // Only written checkpoints can be kept: the next multiple of checkpoint-every.
        base.ppo.checkpoint_every = 5;
        assert_eq!(every(&base), 245);
        base.ppo.checkpoint_every = 1;
        base.reproduce.specialist_candidates = 100;
        base.reproduce.finetune_steps = 4096;
        assert_eq!(every(&base), 1);
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
    fn paired_legs_are_the_legs_both_models_drove() {
        // Part 0: env 0 drove 3 legs under x, 2 under y; env 1 one leg each. Part 1 only x.
        let x: Legs = vec![
            vec![vec![Some(10), None, Some(4)], vec![Some(6)]],
            vec![vec![None]],
        ];
        let y: Legs = vec![vec![vec![Some(12), Some(5)], vec![Some(8)]]];
        let c = Paired::of(&x, &y, 0.1);
        assert_eq!((c.legs, c.reached_by_both), (3, 2));
        assert_eq!(c.success, [200.0 / 3.0, 100.0]);
        // Reach times (1.0, 1.2) and (0.6, 0.8): x 0.2 s sooner on both legs, so ± 0.
        assert!((c.reach[0] - 0.8).abs() < 1e-12 && (c.reach[1] - 1.0).abs() < 1e-12);
        assert!((c.faster.0 - 0.2).abs() < 1e-12 && c.faster.1.abs() < 1e-12);
        // Differences {0, -100, 0} pp: mean -33.3, sd 57.7, t(2) = 4.303.
        let (d, half) = c.difference;
        assert!((d + 100.0 / 3.0).abs() < 1e-9);
        assert!((half - 4.303 * (10_000.0f64 / 3.0).sqrt() / 3f64.sqrt()).abs() < 1e-9);
    }

    #[test]
    fn shape_checks_compare_the_models_leg_by_leg() {
        // One part, one env, `n` legs: leg i reached in `ticks(i)` ticks, or failed.
        let legs = |n: usize, ticks: &dyn Fn(usize) -> Option<u32>| -> Legs {
            vec![vec![(0..n).map(ticks).collect()]]
        };
        let eval = |model: &str, area: AreaKind, legs: Legs| Evaluated {
            model: model.into(),
            area,
            legs,
        };
        let base = legs(100, &|i| (i % 10 != 0).then_some(30 + (i % 7) as u32));
        let mut cells = Vec::new();
        for area in EVAL_AREAS {
            for model in ["general", "FTM", "RTM", "switching"] {
                cells.push(eval(model, area, base.clone()));
            }
        }
        let checks = |cells: &[Evaluated]| shape_checks(cells, 0.1, (0.0, 0.0));
        let md = checks(&cells);
        // Identical legs (mean reach 32.94 ticks): at least as good, and not better.
        assert!(
            row_of(&md, "FTM ≥ general on flat").ends_with(
                "| 100 | 90.0 vs 90.0 | 3.29 vs 3.29 | +0.0 ± 0.0 | +0.00 ± 0.00 | yes |"
            ),
            "{md}"
        );
        assert!(row_of(&md, "switching better than general on mixed").ends_with("| not shown |"));
        // Ties go to the last of the single models, RTM. One tick slower on every leg
        // reached: worse beyond the noise.
        cells[3] = eval(
            "switching",
            AreaKind::Flat,
            legs(100, &|i| (i % 10 != 0).then_some(31 + (i % 7) as u32)),
        );
        assert!(
            row_of(&checks(&cells), "switching ≥ RTM on flat")
                .ends_with("| +0.0 ± 0.0 | -0.10 ± 0.00 | no |")
        );
        // Inside a 0.2 s margin it is not a "no".
        assert!(
            row_of(
                &shape_checks(&cells, 0.1, (1.0, 0.2)),
                "switching ≥ RTM on flat"
            )
            .ends_with("| within margin |")
        );
        // One leg of 100 lost: -1 pp, sd 10, so ± 1.96: within the noise.
        cells[7] = eval(
            "switching",
            AreaKind::Rough,
            legs(100, &|i| {
                (i % 10 != 0 && i != 1).then_some(30 + (i % 7) as u32)
            }),
        );
        assert!(
            row_of(&checks(&cells), "switching ≥ RTM on rough")
                .ends_with("| -1.0 ± 2.0 | +0.00 ± 0.00 | within margin |")
        );
        // Ten more legs reached on the mixed course: +10 pp ± 5.9, better beyond the noise.
        cells[11] = eval(
            "switching",
            AreaKind::Mixed,
            legs(100, &|i| Some(30 + (i % 7) as u32)),
        );
        assert!(
            row_of(&checks(&cells), "switching better than general on mixed")
                .ends_with("| +10.0 ± 5.9 | +0.00 ± 0.00 | yes |")
        );
    }

    #[test]
    fn better_means_one_measure_better_and_the_other_not_short() {
        let legs = |ticks: &dyn Fn(usize) -> Option<u32>| -> Legs {
            vec![vec![(0..200).map(ticks).collect()]]
        };
        let eval = |model: &str, legs: Legs| Evaluated {
            model: model.into(),
            area: AreaKind::Mixed,
            legs,
        };
        let general = eval("general", legs(&|i| Some(40 + (i % 5) as u32)));
        // Six legs of 200 lost (-3.0 pp, sd 17.1, ± 2.4) but 0.3 s sooner on the rest.
        let faster = eval(
            "switching",
            legs(&|i| (i >= 6).then_some(37 + (i % 5) as u32)),
        );
        let row = |margins| {
            row_of(
                &shape_checks(&[general.clone(), faster.clone()], 0.1, margins),
                "switching better than general on mixed",
            )
        };
        // Faster beyond the noise, and the success loss not beyond a 1 pp margin.
        assert!(row((1.0, 0.05)).ends_with("| -3.0 ± 2.4 | +0.30 ± 0.00 | yes |"));
        // Without a margin, the loss is beyond the noise: short.
        assert!(row((0.0, 0.05)).ends_with("| no |"));
    }

    #[test]
    fn the_seeds_report_lines_up_each_claim_across_seeds() {
        let dir = tempfile::tempdir().expect("tempdir");
        let legs = |ticks: u32| -> Legs { vec![vec![vec![Some(ticks); 50]]] };
        // Seed 1's best single model on rough ground is RTM, seed 2's FTM; switching drives
        // like RTM in both.
        let run = |seed: u64, ftm_rough: u32| {
            let out = dir.path().join(format!("seed-{seed}"));
            std::fs::create_dir_all(out.join("d-analysis")).expect("mkdir");
            std::fs::write(
                out.join("d-analysis/results.json"),
                r#"{"windows": [{"window": 70, "accuracy": 0.97}]}"#,
            )
            .expect("results");
            let mut base = Config::default();
            base.run.seed = seed;
            let mut cells = Vec::new();
            for area in EVAL_AREAS {
                for (model, ticks) in [("general", 40), ("FTM", 40), ("RTM", 35), ("switching", 35)]
                {
                    let ticks = if model == "FTM" && area == AreaKind::Rough {
                        ftm_rough
                    } else {
                        ticks
                    };
                    cells.push(Evaluated {
                        model: model.into(),
                        area,
                        legs: legs(ticks),
                    });
                }
            }
            let p = Pipeline {
                base,
                out,
                quiet: true,
            };
            (p, cells)
        };
        let md = seeds_report(&[run(1, 40), run(2, 34)]).expect("report");
        let row = row_of(&md, "switching ≥ the best single model on rough");
        // Seed 1: like RTM, 0 s; seed 2: 0.1 s behind FTM on every leg; t(1) = 12.706.
        assert!(row.contains("| 0.0 ± 0.0 | -0.05 ± 0.64 |"), "{row}");
        assert!(
            row.ends_with(
                "| seed 1: yes (switching ≥ RTM on rough); seed 2: no (switching ≥ FTM on rough) |"
            ),
            "{row}"
        );
        assert!(row_of(&md, "RTM ≥ general on rough").ends_with("| seed 1: yes; seed 2: yes |"));
        assert!(row_of(&md, "70").contains("97.00"), "{md}");
    }

    fn row_of(md: &str, claim: &str) -> String {
        md.lines()
            .find(|l| l.starts_with(&format!("| {claim} |")))
            .unwrap_or_else(|| panic!("no row {claim} in\n{md}"))
            .to_string()
    }
}
