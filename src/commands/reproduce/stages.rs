//! The pipeline's setting ([`Pipeline`]: its base config and output directory) and
//! per-stage bookkeeping: each stage's directory, its `stage.json` done marker, a fresh start
//! for an unfinished one, training runs and the checkpoints they leave.

use super::super::run::execute;
use crate::runtime;
use anyhow::Context;
use common::Config;
use common::config::{AreaKind, PolicySlot};
use common::run_dir::{self, learner_dir};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Several seeds' runs of the pipeline, each with its evaluated cells (stage f's).
pub(super) type Runs = [(Pipeline, Vec<super::legs::Evaluated>)];

/// The pipeline's base config, its output directory and whether it runs quietly.
pub(super) struct Pipeline {
    pub(super) base: Config,
    pub(super) out: PathBuf,
    pub(super) quiet: bool,
}

impl Pipeline {
    /// The terrain kinds the world has an area of: SPEC S8's flat and rough by default.
    pub(super) fn kinds(&self) -> Vec<AreaKind> {
        self.base.sim.terrain.kinds()
    }

    /// Whether the world is the paper's two terrains, where stage d is SPEC S7's analysis;
    /// with more kinds it is `estimator-proc kinds`, whose named classifier estimates online.
    pub(super) fn paper_terrains(&self) -> bool {
        paper_terrains(&self.base)
    }

    /// The base config with `n` envs on each terrain kind's area.
    pub(super) fn envs(&self, n: usize) -> Config {
        let mut c = self.base.clone();
        c.sim.spread(&self.kinds(), n);
        c
    }

    /// `cfg` estimating terrain online with stage d's classifier: with more than the paper's
    /// two terrains, the named K-kind classifier, which is never refitted.
    pub(super) fn estimate_with_stage_d(&self, cfg: &mut Config) {
        if self.paper_terrains() {
            cfg.estimator.model = Some(self.stage_dir("d-analysis").join("results.json"));
        } else {
            cfg.estimator.kinds_model = Some(self.stage_dir("d-analysis").join(KINDS_JSON));
        }
        cfg.estimator.refit_every = 0;
    }
}

/// Whether `cfg`'s world has SPEC S1's flat and rough areas and no other.
fn paper_terrains(cfg: &Config) -> bool {
    cfg.sim.terrain.kinds() == [AreaKind::Flat, AreaKind::Rough]
}

/// Stage d's named classifier with more than two terrain kinds.
const KINDS_JSON: &str = "kinds.json";

impl Pipeline {
    pub(super) fn stage_dir(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }

    pub(super) fn done(&self, name: &str) -> bool {
        self.stage_dir(name).join("stage.json").is_file()
    }

    pub(super) fn finish(&self, name: &str, what: serde_json::Value) -> anyhow::Result<()> {
        let p = self.stage_dir(name).join("stage.json");
        std::fs::write(&p, serde_json::to_string_pretty(&what)?)
            .with_context(|| format!("cannot write {}", p.display()))
    }

    /// What stage `name` kept in its `file`, if it finished; `what` names it in the error
    /// when the file is not that (an older lavatube's).
    pub(super) fn kept<T: serde::de::DeserializeOwned>(
        &self,
        name: &str,
        file: &str,
        what: &str,
    ) -> anyhow::Result<Option<T>> {
        if !self.done(name) {
            return Ok(None);
        }
        let dir = self.stage_dir(name);
        let path = dir.join(file);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text).map(Some).with_context(|| {
            format!(
                "{} is not {what} (an older lavatube's?): remove {} to run stage {name} again",
                path.display(),
                dir.display()
            )
        })
    }

    /// Starts stage `name` afresh (an unfinished earlier attempt is removed).
    pub(super) fn fresh(&self, name: &str) -> anyhow::Result<PathBuf> {
        let dir = self.stage_dir(name);
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .with_context(|| format!("cannot remove the unfinished {}", dir.display()))?;
        }
        Ok(dir)
    }

    /// The shared-memory run id of stage `name`: unique to this process, so two pipelines
    /// (two `--out` directories, or a test beside a long run) never meet on one bus.
    pub(super) fn run_id(&self, name: &str) -> String {
        format!("{name}-{}", std::process::id())
    }

    /// Runs `cfg` on this host as the run `name` (directory and run id); an interruption is
    /// an error that says how to go on.
    pub(super) fn execute(&self, cfg: &Config, name: &str) -> anyhow::Result<()> {
        if !execute(
            cfg,
            name,
            &self.run_id(name),
            (self.quiet, false),
            runtime::Host::Whole,
        )? {
            anyhow::bail!("interrupted during {name}; run again to resume");
        }
        Ok(())
    }

    pub(super) fn say(&self, line: &str) {
        eprintln!("reproduce: {line}");
    }

    /// A training stage: `cfg` run as run `name` in the output directory.
    pub(super) fn train(&self, name: &str, mut cfg: Config) -> anyhow::Result<()> {
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
        self.execute(&cfg, name)?;
        self.finish(name, serde_json::json!({ "stage": name }))
    }

    /// Stage `name`'s checkpoints of the learner for `slot`, oldest first, each with the
    /// update it was taken after.
    pub(super) fn checkpoints(
        &self,
        name: &str,
        slot: PolicySlot,
    ) -> anyhow::Result<Vec<(u64, PathBuf)>> {
        checkpoints_in(&learner_dir(&self.stage_dir(name), slot))
    }

    /// The newest checkpoint of stage `name`'s learner for `slot`.
    pub(super) fn checkpoint(&self, name: &str, slot: PolicySlot) -> anyhow::Result<PathBuf> {
        let newest = self.checkpoints(name, slot)?.pop();
        newest
            .map(|(_, p)| p)
            .with_context(|| format!("stage {name} left no checkpoint"))
    }

    /// Exports a checkpoint's actor to `out` with `learner-proc export`.
    pub(super) fn export(&self, ckpt: &Path, out: &Path) -> anyhow::Result<()> {
        export(ckpt, out, self.base.ppo.obs_clip)
    }
}

/// The checkpoints of the learner whose directory is `learner`, oldest first, each with the
/// update it was taken after; an error when there is none.
pub(crate) fn checkpoints_in(learner: &Path) -> anyhow::Result<Vec<(u64, PathBuf)>> {
    let dir = learner.join(run_dir::CHECKPOINTS);
    let mut files: Vec<(u64, PathBuf)> = std::fs::read_dir(&dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter_map(|p| {
            let update = run_dir::parse_checkpoint_file(p.file_name()?.to_str()?)?;
            Some((update, p))
        })
        .collect();
    files.sort();
    anyhow::ensure!(!files.is_empty(), "no checkpoint in {}", dir.display());
    Ok(files)
}

/// Where an actor's weights are: a `.policy` file, used as it is, or a checkpoint, exported
/// first.
pub(crate) enum Weights {
    File(PathBuf),
    Checkpoint(PathBuf),
}

impl Weights {
    /// A file named on the command line: a checkpoint if it ends in `.ckpt`, else a `.policy`.
    pub(crate) fn of_file(path: PathBuf) -> Self {
        if path.extension().is_some_and(|e| e == "ckpt") {
            Weights::Checkpoint(path)
        } else {
            Weights::File(path)
        }
    }
}

/// Exports a checkpoint's actor to `out` with `learner-proc export`, its observations
/// clipped at `obs_clip` as the learner clipped them.
pub(crate) fn export(ckpt: &Path, out: &Path, obs_clip: f64) -> anyhow::Result<()> {
    let status = Command::new(runtime::locate("learner-proc")?)
        .arg("export")
        .arg(ckpt)
        .arg("--out")
        .arg(out)
        .args(["--obs-clip", &obs_clip.to_string()])
        .status()?;
    anyhow::ensure!(
        status.success(),
        "learner-proc export {} failed",
        ckpt.display()
    );
    Ok(())
}
