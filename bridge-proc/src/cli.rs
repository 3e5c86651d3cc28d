//! `bridge-proc`'s command line: which side of a run across hosts this bridge is.

use crate::{learner_side, sim_side};
use common::Config;

#[derive(Debug, clap::Parser)]
#[command(
    name = "bridge-proc",
    version,
    about = "Carries a lavatube run's rollout chunks and policies between hosts over Zenoh"
)]
pub struct Cli {
    #[command(subcommand)]
    pub side: Side,
}

#[derive(Debug, clap::Subcommand)]
pub enum Side {
    /// On the learner host: listen for sim hosts, republish their chunks, send them policies.
    Learner {
        #[command(flatten)]
        join: common::cli::JoinArgs,
        /// Zenoh endpoint to listen on, tcp/HOST:PORT.
        #[arg(long, value_parser = common::cli::parse_endpoint)]
        listen: String,
    },
    /// On a sim host: connect to the learner host, send it chunks, republish its policies.
    Sim {
        #[command(flatten)]
        join: common::cli::JoinArgs,
        /// The learner host's Zenoh endpoint, tcp/HOST:PORT.
        #[arg(long, value_parser = common::cli::parse_endpoint)]
        connect: String,
        /// This host's source id, which its chunks carry (1 ..= 65535, unique in the run).
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65535))]
        source: u32,
    },
}

/// Runs the chosen side until the run stops it.
pub fn run(cli: &Cli) -> anyhow::Result<()> {
    match &cli.side {
        Side::Learner { join, listen } => {
            let cfg = Config::load(&join.config)?;
            learner_side::run(&cfg, &join.run_id, listen)
        }
        Side::Sim {
            join,
            connect,
            source,
        } => {
            let cfg = Config::load(&join.config)?;
            sim_side::run(&cfg, &join.run_id, connect, *source)
        }
    }
}
