//! The runtime engine under every launcher command: a [`Run`] resolves its config, spawns its
//! processes as [`Child`]ren under their restart policies ([`Supervised`]), swaps learners,
//! and stops them all by one [`ladder`]. `run`, `reproduce`, `bench` and `swap-learner` are
//! thin commands over it.

mod bins;
mod board;
mod child;
mod console;
mod host;
pub mod ladder;
pub mod map;
mod numbers;
mod role;
mod run;
mod summary;
mod supervisor;
mod swap;
mod sweep;

pub use bins::{Binaries, locate};
pub use child::{Child, Output, Usage};
pub use console::{Lines, say};
pub use host::Host;
pub use numbers::thousands;
pub use role::Role;
pub use run::{Finished, LAUNCHER_NODE, ResumedConfig, Run};
pub use summary::{MeanStd, Progress, Summary, coverage_line};
pub use supervisor::{Event, Spec, Supervised};
pub use sweep::{report_sweep, sweep_dead_runs};
