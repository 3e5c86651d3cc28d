//! `[sim.external]`: a gym client acting for the sim (`sim.acting = "external"`, our
//! extension): how long the sim waits for it and what happens when it leaves.

use super::ConfigError;
use super::range::in_range;
use serde::{Deserialize, Serialize};

/// The sim's side of a gym client.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct ExternalConfig {
    /// Seconds the sim waits for the client's next request, the first one included, before
    /// it gives up on the client (died or stalled). [0.1, 86400]. Default 30.
    pub timeout_s: f64,
    /// After a client closes or is given up on, wait for the next one (unbounded) instead of
    /// ending the run. Default false.
    pub stay_up: bool,
}

impl Default for ExternalConfig {
    fn default() -> Self {
        Self {
            timeout_s: 30.0,
            stay_up: false,
        }
    }
}

impl ExternalConfig {
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        in_range("sim.external.timeout-s", self.timeout_s, 0.1, 86_400.0)
    }
}
