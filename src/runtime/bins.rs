//! The process binaries a run starts, found beside the launcher's own executable.

use super::Role;
use crate::error::UserError;
use anyhow::Context;
use std::path::PathBuf;

/// A process binary, looked up beside the launcher's own executable.
pub fn locate(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot find the launcher's own executable")?;
    let dir = exe
        .parent()
        .context("the launcher's executable has no directory")?;
    // Test binaries live one level down, in deps/.
    for d in [dir, dir.parent().unwrap_or(dir)] {
        let p = d.join(name);
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(UserError(format!(
        "cannot find `{name}` beside {}: build the workspace first (cargo build --release --workspace)",
        dir.display()
    ))
    .into())
}

/// Every binary a role may need, located once before anything starts.
#[derive(Debug, Clone)]
pub struct Binaries {
    pub sim: PathBuf,
    pub learner: PathBuf,
    pub estimator: PathBuf,
    pub bridge: PathBuf,
    pub recorder: PathBuf,
    /// This launcher, for its hidden bench subcommands.
    pub launcher: PathBuf,
}

impl Binaries {
    pub fn locate() -> anyhow::Result<Self> {
        Ok(Self {
            sim: locate("sim-proc")?,
            learner: locate("learner-proc")?,
            estimator: locate("estimator-proc")?,
            bridge: locate("bridge-proc")?,
            recorder: locate("recorder-proc")?,
            launcher: std::env::current_exe().context("cannot find the launcher's executable")?,
        })
    }

    pub fn of(&self, role: Role) -> &PathBuf {
        match role {
            Role::Learner(_) => &self.learner,
            Role::Estimator => &self.estimator,
            Role::Sim => &self.sim,
            Role::Bridge => &self.bridge,
            Role::Recorder => &self.recorder,
            Role::Reader | Role::Echo => &self.launcher,
        }
    }
}
