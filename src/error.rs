//! The launcher's errors and what they mean as exit codes.

/// Exit code for user errors (bad config, bad arguments, missing files).
pub use common::cli::EXIT_USER;
/// Exit code for failures of the system itself (a child process failed, shared memory broke).
pub const EXIT_FAILURE: u8 = 2;

/// An error the user can fix: reported as one line with exit code 1.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UserError(pub String);

/// 1 for user and config errors, 2 for the rest.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    if e.downcast_ref::<common::ConfigError>().is_some() || e.downcast_ref::<UserError>().is_some()
    {
        EXIT_USER
    } else {
        EXIT_FAILURE
    }
}
