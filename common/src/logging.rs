//! One logging set-up for every process: `tracing` to stderr, level from `RUST_LOG`
//! (default `info`), colours only on a terminal so log files stay plain text.

use std::io::IsTerminal;

/// Initialises the process's subscriber; a second call is a no-op.
pub fn init() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .try_init();
}
