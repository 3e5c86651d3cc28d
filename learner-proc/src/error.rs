//! The library's one error type; every variant names what it is about (file, field, update).

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum LearnerError {
    /// The learner was built with settings it cannot honour.
    #[error("learner setting `{field}`: {reason}")]
    Setting { field: &'static str, reason: String },

    /// A rollout that does not have the promised shape.
    #[error("malformed rollout: {reason}")]
    Rollout { reason: String },

    /// A loss or gradient went NaN/inf; the update was rolled back.
    #[error("update {update}: non-finite {what}; the learner state was left unchanged")]
    NonFinite { update: u64, what: &'static str },

    /// A burn tensor could not be read back.
    #[error("reading the {what} tensor back from burn: {reason}")]
    Tensor { what: &'static str, reason: String },

    #[error("{op} {path}: {source}")]
    Io {
        op: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// The file is not a checkpoint, or was cut short or damaged.
    #[error("checkpoint {path} is corrupt: {reason}")]
    Corrupt { path: PathBuf, reason: String },

    /// A well-formed checkpoint this learner cannot use (format version, architecture).
    #[error("checkpoint {path} is incompatible: {reason}")]
    Incompatible { path: PathBuf, reason: String },

    /// No checkpoint in the directory could be loaded.
    #[error("no loadable checkpoint in {dir} ({tried} tried){}", newest_error.as_ref().map(|e| format!("; the newest failed: {e}")).unwrap_or_default())]
    NoCheckpoint {
        dir: PathBuf,
        tried: usize,
        newest_error: Option<Box<LearnerError>>,
    },

    #[error("encoding checkpoint state: {reason}")]
    Encode { reason: String },

    #[error("metrics CSV {path}: {source}")]
    Metrics {
        path: PathBuf,
        #[source]
        source: csv::Error,
    },

    /// A metrics CSV that cannot be plotted: a column missing from the header, a value that
    /// is not a number.
    #[error("metrics CSV {path}: {reason}")]
    MetricsFormat { path: PathBuf, reason: String },

    /// plotters or the PNG encoder failed while drawing a figure.
    #[error("drawing {path}: {reason}")]
    Plot { path: PathBuf, reason: String },

    #[error(transparent)]
    Config(#[from] common::ConfigError),

    /// Shared memory failed (a run's services, a message of the wrong type).
    #[error(transparent)]
    Ipc(#[from] common::ipc::IpcError),
}

impl LearnerError {
    pub(crate) fn io(
        op: &'static str,
        path: impl Into<PathBuf>,
    ) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.into();
        move |source| Self::Io { op, path, source }
    }

    pub(crate) fn setting(field: &'static str, reason: impl Into<String>) -> Self {
        Self::Setting {
            field,
            reason: reason.into(),
        }
    }

    pub(crate) fn rollout(reason: impl Into<String>) -> Self {
        Self::Rollout {
            reason: reason.into(),
        }
    }

    /// True for problems the user can fix (bad input file, missing path), as opposed to bugs.
    pub fn is_user_error(&self) -> bool {
        !matches!(
            self,
            Self::NonFinite { .. }
                | Self::Tensor { .. }
                | Self::Encode { .. }
                | Self::Plot { .. }
                | Self::Ipc(_)
        )
    }
}
