//! bridge-proc: carries a run's rollout chunks and policies between hosts over Zenoh
//! (DESIGN §9), so sim hosts can feed a learner host. Inside each host every process still
//! meets on iceoryx2's shared memory; the bridge is one more process of the host's run,
//! reading and writing the same services as a local sim or learner would.
//!
//! - [`frame`]: a message as bytes: type names and sizes, source, sequence number, MAC.
//! - [`link`]: the Zenoh connections and key expressions.
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
pub mod frame;
pub mod learner_side;
pub mod link;
pub mod sim_side;

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Frames and bytes through one direction of a bridge.
#[derive(Debug, Default, Clone, Copy)]
pub struct Counts {
    pub frames: u64,
    pub bytes: u64,
}

impl Counts {
    fn add(&mut self, bytes: usize) {
        self.frames += 1;
        self.bytes += bytes as u64;
    }
}

/// Set when either of a bridge's two threads ends, so the other ends too.
#[derive(Debug, Default, Clone)]
pub struct Stop(Arc<AtomicBool>);

impl Stop {
    fn set(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// Runs `beside` on a thread named `name` and `here` on this one, each until it ends or the
/// other has ended (a bridge's two directions); fails if either failed.
fn both_directions(
    name: &str,
    beside: impl FnOnce(&Stop) -> anyhow::Result<()> + Send + 'static,
    here: impl FnOnce(&Stop) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let stop = Stop::default();
    let thread = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let r = beside(&stop);
                stop.set();
                r
            })?
    };
    let r = here(&stop);
    stop.set();
    let other = thread
        .join()
        .map_err(|_| anyhow::anyhow!("the {name} thread panicked"))?;
    r.and(other)
}

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
    common::logging::init();
    // A bad config is the user's to fix; anything else is unexpected.
    common::cli::exit(cli::run(&cli), |_: &common::config::ConfigError| true)
}
