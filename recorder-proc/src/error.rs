//! The crate's one error type. Every variant names what it is about (file, entity, service)
//! and prints on one line, so a user sees the cause without a backtrace.

use std::path::PathBuf;

/// What can go wrong while recording.
#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    #[error(transparent)]
    Config(#[from] common::ConfigError),
    #[error(transparent)]
    Telemetry(#[from] common::telemetry::TelemetryError),
    #[error("cannot create recording {path}: {reason}")]
    Create { path: PathBuf, reason: String },
    #[error("cannot log `{entity}` to the recording: {reason}")]
    Log { entity: String, reason: String },
    #[error("cannot finish recording {path}: {reason}")]
    Finish { path: PathBuf, reason: String },
    #[error(transparent)]
    Ipc(#[from] common::ipc::IpcError),
}

impl RecorderError {
    /// True when the user can fix it (config, input file, output path); false for a fault of
    /// ours or of the machine.
    pub fn is_user_error(&self) -> bool {
        matches!(
            self,
            RecorderError::Config(_) | RecorderError::Telemetry(_) | RecorderError::Create { .. }
        )
    }
}

/// Shorthand for library results.
pub type Result<T, E = RecorderError> = std::result::Result<T, E>;
