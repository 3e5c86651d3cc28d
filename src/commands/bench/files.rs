//! The bench's files: the config each measurement's processes read, and the JSON files they
//! write when they end.

use anyhow::Context;
use common::Config;
use common::run_dir::CONFIG_TOML;
use std::path::{Path, PathBuf};

/// Makes `dir` and writes `cfg` there as the config its processes read; its path.
pub fn write_config(dir: &Path, cfg: &Config) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let path = dir.join(CONFIG_TOML);
    std::fs::write(&path, cfg.to_toml())
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}

/// The JSON file at `path`, parsed.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("cannot parse {}", path.display()))
}
