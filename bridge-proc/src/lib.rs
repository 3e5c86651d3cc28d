//! bridge-proc: carries a run's rollout chunks and policies between hosts over Zenoh
//! (DESIGN §9), so sim hosts can feed a learner host. Inside each host every process still
//! meets on iceoryx2's shared memory; the bridge is one more process of the host's run,
//! reading and writing the same services as a local sim or learner would.
//!
//! - [`frame`]: a message as bytes: type names and sizes, source, sequence number, MAC.
//! - [`link`]: the Zenoh connections and key expressions.
//! - [`gate`]: connections Zenoh's handshake refused, counted by kind.
//! - [`sim_side`]: on a sim host, chunks out, policies in.
//! - [`learner_side`]: on the learner host, chunks in, policies out.
//!
//! Depends on `common` only among the lavatube crates.
//!
//! Invariants:
//! - A frame that fails its MAC, names other types or sizes, or carries a chunk or policy
//!   that a local receiver would refuse, is counted and dropped; the bridge goes on.
//! - Rollout chunks go with Zenoh's blocking congestion control: none is dropped in transit.
//! - Per-tick telemetry and terrain estimates never leave their host.

pub mod cli;
mod directions;
pub mod frame;
pub mod gate;
pub mod learner_side;
pub mod link;
pub mod sim_side;

pub use directions::{Counts, Stop};

use std::process::ExitCode;

/// Parses `args`, runs, prints any error on one line and maps it to the exit code: 0 ok,
/// 1 a user or config error, 2 anything else.
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli: cli::Cli = match common::cli::parse(args.into_iter().map(Into::into)) {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    common::logging::init_with(Some(gate::layer()));
    // A bad config is the user's to fix; anything else is unexpected.
    common::cli::exit(cli::run(&cli), |_: &common::config::ConfigError| true)
}
