//! Reading the JSON files the bench's processes write when they end.

use anyhow::Context;
use std::path::Path;

/// The JSON file at `path`, parsed.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("cannot parse {}", path.display()))
}
