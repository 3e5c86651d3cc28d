//! One logging set-up for every process: `tracing` to stderr, level from `RUST_LOG`
//! (default `info`), colours only on a terminal so log files stay plain text.

use std::io::IsTerminal;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{Layer, Registry};

/// Initialises the process's subscriber; a second call is a no-op.
pub fn init() {
    init_with(None::<tracing_subscriber::layer::Identity>);
}

/// Initialises the process's subscriber with `extra` beside the log: a layer that watches
/// events under its own filter, whatever `RUST_LOG` lets through to the log. A second call
/// is a no-op.
pub fn init_with<L: Layer<Registry> + Send + Sync>(extra: Option<L>) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let log = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .with_filter(filter);
    let _ = tracing_subscriber::registry()
        .with(extra)
        .with(log)
        .try_init();
}
